import sys

from drltg.cli import main

sys.exit(main())
