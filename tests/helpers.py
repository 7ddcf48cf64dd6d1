"""Helpers shared by several tests and ``benchmarks/bench_methods.py``: geometry builders
(plain NumPy, no randomness of their own: a caller's ``rng`` is drawn from in a fixed order) and
the render context of a solved scene.
"""

from __future__ import annotations

import numpy as np

from daskrad import render
from daskrad.run import solve_scene
from daskrad.settings import Settings


def grid(origin, u, v, n=1):
    """An n × n grid of quads spanning ``origin + s u + t v``, lit side ``u × v``.

    Returns ``vertices (V, 3)`` and ``elem_verts (n*n, 4) int32``. Grid coordinates come from
    one ``linspace``, so grids meeting along an edge share bit-identical vertices.
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
    """The cube [0, size]³, each face an n × n grid, lit sides inwards."""
    x, y, z = np.eye(3) * size
    o = np.zeros(3)
    return merge(
        grid(o, x, y, n), grid(z, y, x, n),          # floor (+z), ceiling (-z)
        grid(o, y, z, n), grid(x, z, y, n),          # x = 0 (+x), x = size (-x)
        grid(o, z, x, n), grid(y, x, z, n),          # y = 0 (+y), y = size (-y)
    )


def square_above(x0, x1, y0, y1, height, n=1):
    """A rectangle in the plane z = height facing down (towards a point below)."""
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


def render_context(scene, **opts):
    """``(ctx, h)``: the render context of ``scene`` solved with ``opts`` over the defaults
    patch 4, element 0.5, 1 sample per pixel, and its hierarchy."""
    settings = Settings(**{"patch_size": 4.0, "element_size": 0.5, "spp": 1, **opts})
    h, _, sol, light = solve_scene(scene, settings)
    return render.context(scene, light, sol, settings, scene.camera), h
