"""Kernels -> C sources, header, Python extension and manifest, written atomically.

Entry point: ``robotgen.emit.pipeline.build`` (a system to its output directory), through
``robotgen.emit.build.emit`` (kernels to files). ``c_kernel`` prints one SX Function as C;
``context`` gathers what the templates/ layouts show (``views`` the parts several modules
share); ``render``, ``manifest`` and ``compile`` make the files; ``build`` writes them all or
nothing.
"""
