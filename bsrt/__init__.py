"""bsrt: direct ray tracing of B-spline and trimmed NURBS surfaces."""

__version__ = "0.2.0"
