import sys

from daskrad.cli import entry

sys.exit(entry())
