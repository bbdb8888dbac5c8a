from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from segadeform.geometry.primitives import grid_plane  # noqa: E402
from segadeform.train import losses as L  # noqa: E402


def _mesh():
    v, f = grid_plane(5, 5, (1.0, 1.0))
    return torch.as_tensor(v, dtype=torch.float32), torch.as_tensor(f, dtype=torch.int64)


def test_supervised_terms_vanish_at_the_target():
    v, f = _mesh()
    from segadeform.geometry.mesh_ops import unique_edges

    e = torch.as_tensor(unique_edges(f.numpy(), len(v)))
    x = v[None].repeat(2, 1, 1)
    assert float(L.vertex_loss(x, x)) == 0 and float(L.edge_loss(x, x, e)) == 0
    assert float(L.normal_loss(x, x, f)) < 1e-6
    assert float(L.stretch_loss(x, v, e)) < 1e-12 and float(L.shear_loss(x, v, f)) < 1e-12
    y = x + torch.tensor([0.0, 0.0, 0.1])
    assert abs(float(L.vertex_loss(y, x)) - 0.1) < 1e-6 and float(L.edge_loss(y, x, e)) < 1e-6  # rigid: no edge error


def test_physics_terms_respond_to_what_they_measure():
    v, f = _mesh()
    from segadeform.geometry.mesh_ops import unique_edges

    e = torch.as_tensor(unique_edges(f.numpy(), len(v)))
    stretched = v * torch.tensor([1.2, 1.0, 1.0])
    assert float(L.stretch_loss(stretched[None], v, e)) > 1e-3
    sheared = v.clone()
    sheared[:, 0] += 0.3 * v[:, 2]  # the grid lies in the xz plane
    assert float(L.shear_loss(sheared[None], v, f)) > 1e-3
    assert (
        float(L.gravity_loss((v - torch.tensor([0, 0.1, 0]))[None], v))
        < 0
        < float(L.gravity_loss((v + torch.tensor([0, 0.1, 0]))[None], v))
    )


def test_collision_loss_pushes_out_along_the_normal():
    p = torch.zeros(1, 3, 3)
    n = torch.tensor([0.0, 1.0, 0.0]).expand(1, 3, 3)
    x = torch.tensor([[[0, 0.01, 0], [0, -0.01, 0], [0, 0.001, 0]]], requires_grad=True)
    loss = L.collision_loss(x, p, n, margin=0.002)
    loss.backward()
    g = x.grad[0]
    assert g[0].abs().sum() == 0  # clear of the margin: no force
    assert g[1, 1] < 0 and g[2, 1] < 0  # inside or too close: descent moves it up (out)


def test_collision_loss_near_counts_only_vertices_simulated_near_the_body():
    """collision_near: the tangent plane at a far simulated vertex's closest body point is no stand-in for the
    body, so such vertices are left out (the mean stays over every vertex); 0 keeps every vertex."""
    p = torch.zeros(1, 2, 3)
    n = torch.tensor([0.0, 1.0, 0.0]).expand(1, 2, 3)
    x = torch.tensor([[[0, -0.01, 0], [0, -0.01, 0]]], requires_grad=True)  # both below their planes
    y = torch.tensor([[[0, 0.005, 0], [0, 0.2, 0]]])  # simulated: one touching the body, one 20 cm off it
    full = L.collision_loss(x, p, n, margin=0.002, power=1)
    near = L.collision_loss(x, p, n, margin=0.002, power=1, near=0.02, y=y)
    assert abs(float(full) - 0.012) < 1e-6 and abs(float(near) - 0.006) < 1e-6
    near.backward()
    assert x.grad[0, 0, 1] < 0 and x.grad[0, 1].abs().sum() == 0
    from segadeform.errors import InputError

    with pytest.raises(InputError, match="needs the simulated vertices"):
        L.collision_loss(x, p, n, near=0.02)
