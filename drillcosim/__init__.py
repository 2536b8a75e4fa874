"""drillcosim: co-simulation of drilling feed drives for sensorless thrust monitoring,
thrust-force control and stack-interface detection.

One installed namespace, five layers (docs/architecture.md):

* :mod:`drillcosim.cosim` -- a generic FMI co-simulation master (knows nothing of drilling);
* :mod:`drillcosim.drilling` -- the drilling domain, given to the master as plug-ins;
* :mod:`drillcosim.controllers` -- the blocks that run inside the loop;
* :mod:`drillcosim.analysis` -- scoring, identification, commissioning, campaigns, figures;
* :mod:`drillcosim.fmus` -- the project's own plant FMUs (C sources, built on first use);

and :mod:`drillcosim.cli`, the ``drillcosim`` command. The shipped scenarios are package
data of :mod:`drillcosim.scenarios`.
"""
from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("drillcosim")
except PackageNotFoundError:      # a checkout on sys.path without an install
    __version__ = "0+unknown"
