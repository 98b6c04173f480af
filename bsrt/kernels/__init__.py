"""Compiled (numba) kernels: the per-ray loops over flat float64/int64 arrays.

No Python objects inside a kernel; one implementation per algorithm. The
first use on a machine compiles them (cached on disk, see ``compile.py``).
"""
