import sys

from cellcal.cli import main

sys.exit(main())
