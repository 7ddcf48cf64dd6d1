"""Test and benchmark support, public like ``numpy.testing``: geometry builders here, the
numerical stress cases of issue 7 in :mod:`daskrad.testing.stress`.

The builders are plain NumPy and import nothing of the project; they have no randomness of their
own (a caller's ``rng`` is drawn from in a fixed order). Each returns the element arrays the
form-factor kernels take: ``vertices : (V, 3) float64`` and ``elem_verts : (E, 4) int32``,
corner indices counter-clockwise seen from the lit side, ``-1`` in column 3 for a triangle.

Nothing in the package imports this one (the import-linter layers put it on top); the test suite
(through ``tests/helpers.py``) and the benchmarks do.
"""

from __future__ import annotations

import numpy as np

__all__ = ["closed_box", "grid", "merge", "square_above", "triangle_soup"]


def grid(origin, u, v, n=1):
    """An n × n grid of quads spanning ``origin + s u + t v``, lit side ``u × v``.

    Returns ``vertices ((n+1)², 3)`` and ``elem_verts (n*n, 4) int32``. Grid coordinates come
    from one ``linspace``, so grids meeting along an edge share bit-identical vertices.
    """
    s = np.linspace(0.0, 1.0, n + 1)
    su, sv = np.meshgrid(s, s, indexing="ij")
    verts = (np.asarray(origin, float) + su[..., None] * np.asarray(u, float)
             + sv[..., None] * np.asarray(v, float)).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    elems = np.stack([a, a + n + 1, a + n + 2, a + 1], axis=-1).astype(np.int32)
    return verts, elems


def merge(*parts):
    """One ``(vertices, elem_verts)`` of several, indices shifted (``-1`` kept)."""
    verts, elems, offset = [], [], 0
    for v, e in parts:
        verts.append(v)
        elems.append(np.where(e >= 0, e + offset, -1))
        offset += len(v)
    return np.concatenate(verts), np.concatenate(elems).astype(np.int32)


def closed_box(n, size=1.0):
    """The cube ``[0, size]³``, each face an n × n grid, lit sides inwards."""
    x, y, z = np.eye(3) * size
    o = np.zeros(3)
    return merge(
        grid(o, x, y, n), grid(z, y, x, n),          # floor (+z), ceiling (-z)
        grid(o, y, z, n), grid(x, z, y, n),          # x = 0 (+x), x = size (-x)
        grid(o, z, x, n), grid(y, x, z, n),          # y = 0 (+y), y = size (-y)
    )


def square_above(x0, x1, y0, y1, height, n=1):
    """The rectangle ``[x0, x1] × [y0, y1]`` in the plane ``z = height`` facing down (towards a
    point below), as an n × n grid."""
    return grid([x0, y0, height], [0, y1 - y0, 0], [x1 - x0, 0, 0], n)


def triangle_soup(rng, n):
    """``n`` random triangles around normal centres, and 3 random shooters.

    Returns ``vertices (3n, 3)``, ``elem_verts (n, 4) int32`` (``-1`` in column 3),
    ``points (3, 3)`` and ``normals (3, 3)`` (not unit), drawn from ``rng`` in that order.
    """
    centres = rng.normal(size=(n, 3)) * 2
    tris = centres[:, None, :] + rng.normal(size=(n, 3, 3)) * 0.7
    verts = tris.reshape(-1, 3)
    elems = np.column_stack([np.arange(3 * n).reshape(n, 3), -np.ones(n)]).astype(np.int32)
    points = rng.normal(size=(3, 3))
    normals = rng.normal(size=(3, 3))
    return verts, elems, points, normals
