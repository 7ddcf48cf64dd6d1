"""T-vertex resolution for adaptive subdivision (docs/design.md §3)."""

from __future__ import annotations

from daskrad.kernels._jit import jit


@jit
def resolve_tvertices_kernel(values, vertex, a, b):
    """Set ``values[vertex[i]] = (values[a[i]] + values[b[i]]) / 2`` in place, in order.

    values : (V, k) float64
    vertex, a, b : (T,) int64
        T-vertices and the ends of the edge each lies on, ``vertex`` increasing; ends are older
        vertices, so a T-vertex whose end is itself a T-vertex sees the end's resolved value.
    """
    for i in range(vertex.shape[0]):
        for c in range(values.shape[1]):
            values[vertex[i], c] = 0.5 * (values[a[i], c] + values[b[i], c])
