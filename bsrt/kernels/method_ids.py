"""The seeded root finders' ids, as the compiled kernels take them (their names:
bsrt/methods.py). A module of its own, without numba, so that the method
registry costs nothing to import."""

GRADIENT, FAST, NEWTON = 0, 1, 2
