"""``python -m drltg``: the ``drltg`` command."""
import sys

from drltg.cli import main

sys.exit(main())
