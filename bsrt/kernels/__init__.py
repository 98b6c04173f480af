"""Compiled (numba) kernels: the per-ray loops over flat float64/int64 arrays.

No Python objects inside a kernel; one implementation per algorithm. The
first use on a machine compiles them, cached on disk in the user's cache
folder (``jit.py`` says where); ``compile.py`` compiles them all ahead of
time. Importing this package costs nothing: numba loads with the first
kernel module. Imports nothing of bsrt outside this package (but the
version, in ``jit.py``).
"""
