"""Kernels -> C sources, header, Python extension and manifest, written atomically.

Entry point: ``robotgen.emit.build.emit``. ``c_kernel`` prints one SX Function as C;
``context`` gathers what the templates/ layouts show; ``render``, ``manifest`` and
``compile`` make the files; ``build`` writes them all or nothing.
"""
