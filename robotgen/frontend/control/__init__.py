"""CONTROL from a spec: the node and its gains (node.py), one module per law with settings of
its own (resolved_rate.py)."""
