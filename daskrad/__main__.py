import sys

from daskrad.cli import main

sys.exit(main())
