from robotgen.cli import entry

entry()
