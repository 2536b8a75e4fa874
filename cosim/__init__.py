"""drillcosim co-simulation master: FMU slaves, Python blocks, algorithm, recording, scenarios."""
