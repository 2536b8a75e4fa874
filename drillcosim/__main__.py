"""``python -m drillcosim``: the ``drillcosim`` command."""
import sys

from drillcosim.cli import main

sys.exit(main())
