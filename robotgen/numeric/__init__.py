"""Build-time arithmetic that gives the same bits on every machine: exact constants, the Riccati equation, the
optimal linear servo."""
