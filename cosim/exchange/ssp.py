"""SSP 1.0 (System Structure and Parameterization): scenarios out, other tools' systems in.

* :func:`drillcosim.cosim.exchange.ssp_writer.export_ssp` (``drillcosim export-ssp``): a scenario as an SSP
  package -- ``SystemStructure.ssd``, the plant FMUs and the exported block FMUs in
  ``resources/``, parameter values in SSV files, connections with their unit conversion
  as ``ssc:LinearTransformation``; what SSP cannot say is refused or listed;
* :func:`drillcosim.cosim.exchange.ssp_reader.load_ssp` (``drillcosim run X.ssp``): an SSP package written by
  another tool, validated against the SSP schema (``schema/``), translated into the same
  :class:`drillcosim.cosim.scenario.build.Scenario` a TOML file gives, so it runs with the same
  supervision, recording and summary.

The SSP 1.0 XSDs in ``schema/`` (and the SSP 2.0 ones in ``schema/2.0/``, for SSDs that
declare version 2.0) are the Modelica Association Project "SSP"'s, BSD 2-clause (the
licence is in each file's header), taken from OpenModelica/OMSimulator ``schema/ssp``
(commit 661db674 for 1.0, 2940ef11 for 2.0). docs/export.md says what is supported.
"""
from __future__ import annotations

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
    "ssb": "http://ssp-standard.org/SSP1/SystemStructureSignalDictionary",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
DRILLCOSIM_NS = "https://github.com/drillcosim/ssp"   # our annotations: what the package does not carry
