"""A forest of search trees in one growing NumPy buffer.

All nodes of all trees live in a single ``(capacity, dim)`` array with parallel parent and
tree-id arrays, so the nearest node over the whole forest (Algorithm 1's ``NearestTree``) is a
single vectorised distance computation. The metric is a weighted Euclidean distance
``d(a, b) = sqrt(sum_i w_i * (a_i - b_i) ** 2)``.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

_NO_PARENT = -1


def check_weights(weights: Iterable[float] | np.ndarray | None, dim: int) -> np.ndarray:
    """Per-joint distance weights as a ``(dim,)`` array (all ones for ``None``)."""
    if weights is None:
        return np.ones(dim)
    w = np.asarray(weights, dtype=float)
    if w.shape != (dim,):
        raise ValueError(f"distance weights must have shape ({dim},), got {w.shape}")
    if not (np.isfinite(w).all() and (w > 0).all()):
        raise ValueError("distance weights must be finite and strictly positive")
    return w


def weighted_distance(a: np.ndarray, b: np.ndarray, weights: np.ndarray) -> float:
    """``sqrt(sum(w * (a - b) ** 2))`` for two configurations."""
    diff = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return float(np.sqrt(np.dot(weights * diff, diff)))


class Forest:
    """Trees rooted at configurations; node indices are global across the forest."""

    def __init__(
        self,
        dim: int,
        weights: Iterable[float] | np.ndarray | None = None,
        capacity: int = 256,
    ):
        if dim < 1:
            raise ValueError(f"dim must be a positive integer, got {dim}")
        self.dim = int(dim)
        self.weights = check_weights(weights, self.dim)
        capacity = max(1, int(capacity))
        self._q = np.empty((capacity, self.dim))
        self._parent = np.empty(capacity, dtype=np.int64)
        self._tree = np.empty(capacity, dtype=np.int64)
        self._n = 0
        self._roots: list[int] = []

    @property
    def n_nodes(self) -> int:
        """Number of nodes over all trees."""
        return self._n

    @property
    def n_trees(self) -> int:
        """Number of trees (= roots)."""
        return len(self._roots)

    @property
    def configs(self) -> np.ndarray:
        """Read-only view of all node configurations, shape ``(n_nodes, dim)``."""
        view = self._q[: self._n]
        view.flags.writeable = False
        return view

    def _append(self, q: np.ndarray, parent: int, tree: int) -> int:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.dim,):
            raise ValueError(f"configuration must have shape ({self.dim},), got {q.shape}")
        if not np.isfinite(q).all():
            raise ValueError("configuration must be finite (found NaN or inf)")
        if self._n == len(self._q):
            cap = 2 * len(self._q)
            self._q = np.concatenate([self._q, np.empty((cap - len(self._q), self.dim))])
            self._parent = np.concatenate([self._parent, np.empty(cap - len(self._parent), int)])
            self._tree = np.concatenate([self._tree, np.empty(cap - len(self._tree), int)])
        idx = self._n
        self._q[idx] = q
        self._parent[idx] = parent
        self._tree[idx] = tree
        self._n += 1
        return idx

    def add_root(self, q: np.ndarray) -> int:
        """Start a new tree at ``q``; returns its tree id."""
        tree_id = len(self._roots)
        self._roots.append(self._append(q, _NO_PARENT, tree_id))
        return tree_id

    def add_node(self, q: np.ndarray, parent: int) -> int:
        """Add ``q`` as a child of node ``parent`` (same tree); returns the node index."""
        if not 0 <= parent < self._n:
            raise IndexError(f"parent node {parent} does not exist (forest has {self._n} nodes)")
        return self._append(q, parent, int(self._tree[parent]))

    def config(self, idx: int) -> np.ndarray:
        """A copy of node ``idx``'s configuration."""
        self._check(idx)
        return self._q[idx].copy()

    def parent(self, idx: int) -> int:
        """Parent node index of ``idx`` (-1 for a root)."""
        self._check(idx)
        return int(self._parent[idx])

    def tree_of(self, idx: int) -> int:
        """Tree id of node ``idx``."""
        self._check(idx)
        return int(self._tree[idx])

    def root_of(self, idx: int) -> int:
        """Node index of the root of the tree containing node ``idx``."""
        return self._roots[self.tree_of(idx)]

    def root_config(self, tree_id: int) -> np.ndarray:
        """A copy of the root configuration of tree ``tree_id``."""
        return self._q[self._roots[tree_id]].copy()

    def path_to_root(self, idx: int) -> np.ndarray:
        """Configurations from node ``idx`` up to its root, shape ``(k, dim)``, ``idx`` first."""
        self._check(idx)
        chain = [idx]
        while self._parent[chain[-1]] != _NO_PARENT:
            chain.append(int(self._parent[chain[-1]]))
        return self._q[chain].copy()

    def nearest(self, q: np.ndarray, exclude_trees: Iterable[int] = ()) -> tuple[int, int] | None:
        """``(tree_id, node_idx)`` of the node nearest to ``q``, skipping ``exclude_trees``.

        Returns ``None`` when the forest has no eligible node.
        """
        if self._n == 0:
            return None
        diff = self._q[: self._n] - np.asarray(q, dtype=float)
        d2 = (diff * diff) @ self.weights
        excluded = list(exclude_trees)
        if excluded:
            mask = np.zeros(self.n_trees, dtype=bool)
            mask[excluded] = True
            d2[mask[self._tree[: self._n]]] = np.inf
        idx = int(np.argmin(d2))
        if not np.isfinite(d2[idx]):
            return None
        return int(self._tree[idx]), idx

    def distance(self, a: np.ndarray, b: np.ndarray) -> float:
        """Weighted distance between two configurations under this forest's weights."""
        return weighted_distance(a, b, self.weights)

    def _check(self, idx: int) -> None:
        if not 0 <= idx < self._n:
            raise IndexError(f"node {idx} does not exist (forest has {self._n} nodes)")
