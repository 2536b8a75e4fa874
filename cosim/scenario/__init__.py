"""Scenarios: TOML files loaded, extended, overridden, checked and built into a System;
the role bindings of FMUs, the plug-in registry, sweeps and the path rule."""
