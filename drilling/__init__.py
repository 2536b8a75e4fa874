"""The drilling domain: the role contract of a drilling plant, the hole plan and its
material presets, the catalogue of the project's own plant FMUs. It reaches the generic
master (:mod:`drillcosim.cosim`) only as plug-ins (:mod:`drillcosim.drilling.plugin`)."""
