"""The hierarchy's table: the one declaration of the arrays the traversal kernels read.

Built by ``bsrt.rendering.bvh.build_bvh`` (whose ``BVH`` holds it as
``arrays`` and adds what only Python needs); read by ``traverse.py``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class BVHArrays(NamedTuple):
    """Flat pieces (leaves) in a bounding volume hierarchy. L leaves, stored in
    tree order (each node's leaves are contiguous), K nodes (node 0 the root):

    node_bounds: (K, 6) float64, (min x, y, z, max x, y, z) of each node
      (the union of its leaves' boxes).
    node_left, node_right: (K,) int64 children, -1 for a tree leaf.
    node_first, node_count: (K,) int64, the node's leaves are
      first .. first + count - 1 (every node, inner ones included).
    leaf_surface: (L,) int64, surface index.
    leaf_rect: (L, 4) float64, (u0, u1, v0, v1) in the surface's knot domain.
    leaf_obb: (L, 15) float64, oriented box of the piece's projected control
      points: centre (3), three orthonormal axes (3 x 3, row k = axis k;
      axis 0 ~ u, axis 1 ~ v, axis 2 ~ the corners' normal), half extents
      (3), padded by the hierarchy's padding.
    patch_net: (P, Pm, Qm, 4) float64, every patch's homogeneous Bezier net
      (Pm, Qm the largest p + 1, q + 1; a net of degree (p, q) fills the
      [:p + 1, :q + 1] corner, the rest is zero).
    leaf_net: (R, Pm, Qm, 4) float64, the nets of the pieces of cut patches.
    leaf_net_row: (L,) int64, where each leaf's net is: leaf_net[r] for
      r >= 0, patch_net[-1 - r] for a patch that is its own leaf (no copy;
      nets.leaf_net).
    leaf_degree: (L, 2) int64, (p, q) of the piece.
    leaf_planar: (L,) bool, the piece's control points lie in one plane
      (its oriented box has no thickness beyond the padding).
    leaf_kept: (L,) bool, the surface's trims keep all of the piece's
      rectangle (trim.rect_state INSIDE; True on untrimmed surfaces).
    """

    node_bounds: np.ndarray
    node_left: np.ndarray
    node_right: np.ndarray
    node_first: np.ndarray
    node_count: np.ndarray
    leaf_surface: np.ndarray
    leaf_rect: np.ndarray
    leaf_obb: np.ndarray
    patch_net: np.ndarray
    leaf_net: np.ndarray
    leaf_net_row: np.ndarray
    leaf_degree: np.ndarray
    leaf_planar: np.ndarray
    leaf_kept: np.ndarray
