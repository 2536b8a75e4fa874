"""FMI slaves: one FMU instance (co-simulation or Model Exchange), its variable types and
units, the FMI frame and compile rule for FMUs the master writes, conformance checks."""
