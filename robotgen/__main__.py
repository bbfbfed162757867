"""python -m robotgen: the command line (robotgen.cli)."""
import sys

try:
    from robotgen.cli import entry
except KeyboardInterrupt:  # Ctrl-C while Python imports robotgen: nothing was done yet
    sys.stderr.write("robotgen: interrupted\n")
    sys.exit(130)

entry()
