"""Exchange with other tools: a block with a C step exported as an FMI co-simulation FMU
(:mod:`~drillcosim.cosim.exchange.export_fmu`), a scenario written as an SSP 1.0 package
(:mod:`~drillcosim.cosim.exchange.ssp_writer`), and an SSP package from another tool read as a
scenario (:mod:`~drillcosim.cosim.exchange.ssp_reader`, a scenario format plug-in); the SSP
namespaces and schemas in :mod:`~drillcosim.cosim.exchange.ssp` and ``schema/``."""
