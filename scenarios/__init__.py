"""The shipped scenarios, plant bindings, commissioning files, stacks and sweeps (package
data: ``drillcosim list`` and ``drillcosim run NAME`` find them from any folder)."""
