"""`python -m iotad.cli` is the `iotad` command (the launcher starts its recorder this way)."""
import sys

from . import main

sys.exit(main())
