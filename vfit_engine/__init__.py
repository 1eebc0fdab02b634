"""vfit engine: body model, measurements, morphing, garments and cloth simulation.

Importing the package is cheap: numba is imported only by the kernel modules,
which are loaded on first use.
"""
__version__ = "0.1.0"
