"""Physics self-supervision: cloth energies on garment x body x motion pairs that were never simulated.

Simulated ground truth is scarce (a Blender sample costs about a minute on two cores), while garments,
bodies and motions can be combined without limit.  Following HOOD and SNUG, a training step on such a
pair needs no target: the network's frames are scored by the energy an implicit-Euler cloth step
minimises, with the two previous frames (the network's own, detached) as the history::

    E(x_t) = E_stretch + E_bend + E_gravity + E_inertia + E_collision

    E_stretch   = sum_e  k_s A_e (|x_i - x_j| / l0_e - 1)^2 / 2          (edge springs, membrane)
    E_bend      = sum_h  k_b 3 l0_h^2 / (A_1 + A_2) (theta_h - theta0_h)^2 / 2   (discrete shells hinge)
    E_gravity   = sum_v  m_v g y_v
    E_inertia   = sum_v  m_v |x_t - 2 x_{t-1} + x_{t-2}|^2 / (2 h^2)
    E_damping   = sum_v  c_d m_v |x_t - x_{t-1}|^2 / (2 h)                  (air drag, Rayleigh)
    E_collision = sum_v  k_c A_v max(eps - d_v, 0)^3                        (d: signed body distance)

with ``A_e`` a third of the rest area of the faces at edge ``e``, ``A_v`` likewise per vertex and
``m_v = rho A / N`` (the garment's mass ``rho A`` shared equally, as Blender's cloth shares it).  The
stiffnesses and drag need not be guessed: :func:`calibrate_material` fits them to simulated frames
(the frames should be stationary points of E given their history).  The loss is ``E / (M g)`` (M the garment's mass):
metres of equivalent height,
the unit of the supervised vertex term, so one weight balances the two.  ``d_v`` is measured against
the posed body at the detached prediction (closest point and outward normal, then linearised), as the
supervised collision term does with the simulated vertex.

Shapes follow :mod:`.losses`: ``x (B, N, 3)``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from collections import OrderedDict
from pathlib import Path

import numpy as np
import torch

from ..body.collision import BodyProxy
from ..body.drape import skinned_rest
from ..body.model import BodyModel
from ..body.transfer import garment_weights
from ..dataset.config import DatasetConfig, load_dataset_config
from ..dataset.make import _garment_file, _motion, check_splits, sample_plan
from ..errors import InputError
from ..geometry.mesh_ops import unique_edges
from ..io import read_mesh
from ..io.location import open_location
from ..motion.motion import history_inputs, motion_windows

__all__ = [
    "Material",
    "ClothTopology",
    "cloth_topology",
    "cloth_energy",
    "dihedral_angles",
    "PhysicsPairs",
    "PairItem",
    "body_contact",
    "vertex_masses",
]


@dataclasses.dataclass(frozen=True)
class Material:
    """Cloth constants (SI).  Defaults: a light cotton, nearly inextensible (HOOD's order of magnitude).

    Attributes:
        density: kg / m^2.  stretch: k_s, N / m.  bending: k_b, N m.  collision: k_c, J / m^5.
        margin: eps, the distance kept from the body (m).  gravity: m / s^2 along -y.
        damping: c_d, 1 / s (air drag).
    """

    density: float = 0.2
    stretch: float = 2.0e4
    bending: float = 4.0e-5
    collision: float = 1.0e7
    margin: float = 0.003
    gravity: float = 9.81
    damping: float = 0.0

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise InputError(f"Material.{f.name} must be a finite number >= 0", got=v)
        if self.density <= 0:
            raise InputError("Material.density must be positive", got=self.density)


@dataclasses.dataclass
class ClothTopology:
    """What the energies need of a rest garment (torch tensors; float32, int64)."""

    edges: torch.Tensor  # (E, 2)
    rest_len: torch.Tensor  # (E,)
    edge_area: torch.Tensor  # (E,) a third of the adjacent faces' rest area
    hinges: torch.Tensor  # (H, 4): the shared edge (i, j) and the two opposite vertices (k, l)
    hinge_rest: torch.Tensor  # (H,) rest dihedral angles
    hinge_stiff: torch.Tensor  # (H,) 3 l0^2 / (A_1 + A_2)
    vertex_area: torch.Tensor  # (N,)

    def to(self, device) -> ClothTopology:
        return ClothTopology(**{f.name: getattr(self, f.name).to(device) for f in dataclasses.fields(self)})


def cloth_topology(rest: np.ndarray, faces: np.ndarray) -> ClothTopology:
    """Edges, hinges and rest measures of the garment ``rest (N, 3)``, ``faces (F, 3)``."""
    v = np.asarray(rest, np.float64)
    f = np.asarray(faces, np.int64)
    n = len(v)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or not len(f):
        raise InputError("a garment needs vertices (N, 3) and triangles (F, 3)", got=(v.shape, f.shape))
    cr = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    varea = np.bincount(f.ravel(), np.repeat(area / 3.0, 3), minlength=n)
    edges = unique_edges(f, n)
    # every face edge (sorted) with its face and opposite corner -> edge areas and hinges
    fe = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    opp = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    fid = np.tile(np.arange(len(f)), 3)
    key = np.sort(fe, axis=1)
    k = key[:, 0] * n + key[:, 1]
    order = np.argsort(k, kind="stable")
    ks = k[order]
    ekey = edges[:, 0].astype(np.int64) * n + edges[:, 1]
    eidx = np.searchsorted(ekey, ks)
    earea = np.bincount(eidx, area[fid[order]] / 3.0, minlength=len(edges))
    first = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[first, len(ks)])
    two = first[count == 2]  # interior edges shared by exactly two faces
    a, b = order[two], order[two + 1]
    # orient each hinge along the first face's edge so that the normals below are consistent
    hinges = np.stack([fe[a, 0], fe[a, 1], opp[a], opp[b]], axis=1)
    l0 = np.linalg.norm(v[hinges[:, 0]] - v[hinges[:, 1]], axis=1)
    hs = 3.0 * l0**2 / np.maximum(area[fid[a]] + area[fid[b]], 1e-20)
    rest_len = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
    t = lambda x, dt=torch.float32: torch.as_tensor(np.ascontiguousarray(x), dtype=dt)  # noqa: E731
    topo = ClothTopology(
        edges=t(edges, torch.int64),
        rest_len=t(np.maximum(rest_len, 1e-9)),
        edge_area=t(earea),
        hinges=t(hinges, torch.int64),
        hinge_rest=torch.zeros(len(hinges)),
        hinge_stiff=t(hs),
        vertex_area=t(varea),
    )
    topo.hinge_rest = dihedral_angles(t(v)[None], topo.hinges)[0]
    return topo


def vertex_masses(topo: ClothTopology, mat: Material) -> torch.Tensor:
    """``m_v (N,)``: the garment's mass ``rho A`` shared equally by its vertices."""
    n = topo.vertex_area.shape[0]
    return torch.full_like(topo.vertex_area, mat.density * float(topo.vertex_area.sum()) / max(n, 1))


def dihedral_angles(x: torch.Tensor, hinges: torch.Tensor) -> torch.Tensor:
    """Signed bending angle of every hinge (0 when flat).  x (B, N, 3), hinges (H, 4) -> (B, H)."""
    xi, xj, xk, xl = (x[:, hinges[:, c]] for c in range(4))
    e = xj - xi
    n1 = torch.cross(e, xk - xi, dim=-1)
    n2 = torch.cross(xl - xi, e, dim=-1)
    en = e / e.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    # atan2(|n1 x n2| signed along e, n1 . n2): smooth, no acos at +-1
    sin = (torch.cross(n1, n2, dim=-1) * en).sum(-1)
    cos = (n1 * n2).sum(-1)
    return torch.atan2(sin, cos)


def cloth_energy(
    x: torch.Tensor,
    topo: ClothTopology,
    mat: Material,
    *,
    prev: torch.Tensor | None = None,
    prev2: torch.Tensor | None = None,
    dt: float = 1 / 30,
    contact_p: torch.Tensor | None = None,
    contact_n: torch.Tensor | None = None,
    height_ref: torch.Tensor | None = None,
) -> dict:
    """Every energy term of frames ``x (B, N, 3)`` divided by ``M g`` (metres), and their sum ``total``.

    ``prev``/``prev2 (B, N, 3)``: the two frames before each (detached history; the inertia term is
    left out without them).  ``contact_p``/``contact_n (B, N, 3)``: closest body point and outward normal
    per vertex (the collision term is left out without them).  ``height_ref (B,)``: subtracted from the
    heights in the gravity term (e.g. the root's), which changes its value, not its gradient."""
    m = vertex_masses(topo, mat)  # (N,)
    mg = float(m.sum()) * max(mat.gravity, 1e-12)
    ed = topo.edges
    length = (x[:, ed[:, 0]] - x[:, ed[:, 1]]).norm(dim=-1)
    out = {"stretch": 0.5 * mat.stretch * (topo.edge_area * (length / topo.rest_len - 1) ** 2).sum(-1)}
    if len(topo.hinges):
        dth = dihedral_angles(x, topo.hinges) - topo.hinge_rest
        dth = torch.remainder(dth + np.pi, 2 * np.pi) - np.pi
        out["bend"] = 0.5 * mat.bending * (topo.hinge_stiff * dth**2).sum(-1)
    else:
        out["bend"] = x.new_zeros(x.shape[0])
    y = x[..., 1] if height_ref is None else x[..., 1] - height_ref[:, None]
    out["gravity"] = mat.gravity * (m * y).sum(-1)
    if prev is not None and prev2 is not None:
        acc = x - 2 * prev + prev2
        out["inertia"] = (m * (acc**2).sum(-1)).sum(-1) / (2 * dt * dt)
    else:
        out["inertia"] = x.new_zeros(x.shape[0])
    if prev is not None and mat.damping:
        out["damping"] = mat.damping * (m * ((x - prev) ** 2).sum(-1)).sum(-1) / (2 * dt)
    else:
        out["damping"] = x.new_zeros(x.shape[0])
    if contact_p is not None and contact_n is not None:
        d = ((x - contact_p) * contact_n).sum(-1)
        out["collision"] = mat.collision * (topo.vertex_area * torch.relu(mat.margin - d) ** 3).sum(-1)
    else:
        out["collision"] = x.new_zeros(x.shape[0])
    out = {k: v.mean() / mg for k, v in out.items()}
    out["total"] = sum(out.values())
    return out


def body_contact(points: np.ndarray, posed: np.ndarray, faces, collider=None) -> tuple[np.ndarray, np.ndarray]:
    """Closest body point and outward normal for every point.  points (B, N, 3), posed (B, V, 3) ->
    (B, N, 3) twice (float32).  ``collider``: a :class:`~segadeform.body.collision.BodyCollider` of the
    body (exact and fast; built once), else a :class:`~segadeform.body.collision.BodyProxy` per frame."""
    cp = np.empty(points.shape, np.float32)
    cn = np.empty(points.shape, np.float32)
    proxy = None
    for b in range(len(points)):
        if collider is not None:
            q = collider.query(np.asarray(points[b], np.float64), posed[b])
        else:
            proxy = BodyProxy(posed[b], faces) if proxy is None else proxy.moved(posed[b])
            q = proxy.query(np.asarray(points[b], np.float64))
        cp[b], cn[b] = q.closest, q.normal
    return cp, cn


@dataclasses.dataclass
class PairItem:
    """A garment x body x motion pair with no simulation: what the network and the energies need."""

    id: str
    features: torch.Tensor  # (1, N, F)
    nbr: torch.Tensor  # (N, K)
    mask: torch.Tensor  # (N, K)
    descriptor: torch.Tensor  # (1, N*)
    betas: torch.Tensor  # (1, |beta|)
    joints: torch.Tensor  # (S, 3)
    rest: torch.Tensor  # (N, 3) the rest the deformer skins (moved toward its drape by rest_drape)
    windows: torch.Tensor  # (T, W, 3 S)
    history_in: torch.Tensor  # (L + T, 3 S + 3) the motion history's inputs from the lead's first frame
    lead: int  # L, the lead's frames (history_in[lead + t] is frame t), as a sample's
    trans: torch.Tensor  # (T, 3)
    body_weights: torch.Tensor  # (N, S)
    posed_body: np.ndarray  # (T, V, 3) float32
    topo: ClothTopology
    fps: float

    @property
    def n_frames(self) -> int:
        return int(self.windows.shape[0])

    def to(self, device) -> PairItem:
        if torch.device(device).type == "cpu":
            return self
        kw = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        kw.update({k: v.to(device) for k, v in kw.items() if isinstance(v, torch.Tensor)})
        return PairItem(**kw)


class PhysicsPairs:
    """The training pairs of a dataset config, for self-supervised steps (none of them need be simulated).

    Only ``train`` pairs of the plan are used, less those matching an ``exclude`` glob
    (:func:`~segadeform.dataset.make.check_splits` refuses a
    config that would leak a held-out garment kind, motion family or body into them).  Garments are
    made once per (garment, body) into ``cache`` (the same files ``dataset make`` writes); the last
    ``keep`` pairs, garments and motions used are kept in memory (a plan of thousands of pairs, each
    motion's posed body ~10 MB, does not fit).
    """

    def __init__(
        self,
        config,
        cache,
        body: BodyModel,
        *,
        n_star: int,
        window: int,
        n_betas: int,
        weight_prior: str = "nearest",
        rest_drape: float = 0.0,
        exclude=(),
        keep: int = 48,
    ) -> None:
        # MakeHuman files may be absent: garments made beside ../shared are read from the cache (_garment_file)
        self.cfg: DatasetConfig = (
            config if isinstance(config, DatasetConfig) else load_dataset_config(config, require_files=False)
        )
        plan = sample_plan(self.cfg)
        check_splits(self.cfg, plan)
        import fnmatch

        # `exclude`: globs of pair ids left out, as a training config's [data] exclude
        self.plan = [p for p in plan if p.split == "train" and not any(fnmatch.fnmatchcase(p.id, g) for g in exclude)]
        if not self.plan:
            raise InputError("the physics pairs' config has no training samples", got=str(self.cfg.path))
        self.cache = Path(cache)
        self.body = body
        self.n_star, self.window, self.n_betas = int(n_star), int(window), int(n_betas)
        self.weight_prior = weight_prior
        self.rest_drape = float(rest_drape)
        self._drapes: dict = {}
        self.keep = int(keep)
        self._items: OrderedDict = OrderedDict()
        self._garments: OrderedDict = OrderedDict()
        self._motions: OrderedDict = OrderedDict()

    def __len__(self) -> int:
        return len(self.plan)

    def _garment(self, gi: int, bi: int):
        key = (gi, bi)
        if key not in self._garments:
            from ..geometry.precompute import PRECOMPUTE_VERSION, precompute_garment
            from ..io.garment_asset import GarmentAsset

            self.cache.mkdir(parents=True, exist_ok=True)
            rel = _garment_file(open_location(self.cache), self.cfg, gi, bi, self.body)
            mesh = read_mesh(self.cache / rel)
            betas = self.cfg.bodies[bi] or None
            joints = self.body.rest_joints(betas)[0]
            h = hashlib.sha256(
                np.ascontiguousarray(mesh.vertices).tobytes()
                + np.ascontiguousarray(mesh.faces).tobytes()
                + np.ascontiguousarray(joints).tobytes()
                + f"{self.n_star}-p{PRECOMPUTE_VERSION}".encode()
            ).hexdigest()[:24]
            p = self.cache / "assets" / f"asset-{h}.npz"
            if p.is_file():
                asset = GarmentAsset.load(p)
            else:
                asset = precompute_garment(
                    mesh.vertices, mesh.faces, joints, n_star=self.n_star, source_name=self.cfg.garments[gi].name
                )
                p.parent.mkdir(exist_ok=True)
                asset.save(p)
            bw = garment_weights(mesh.vertices, mesh.faces, self.body, betas, self.weight_prior)
            # the cloth's own rest (the A-posed garment the simulator drapes, when made) sets the rest lengths
            cloth = self.cache / (rel[: -len(".obj")] + ".cloth.obj")
            cloth_rest = read_mesh(cloth).vertices if cloth.is_file() else mesh.vertices
            self._garments[key] = (mesh, asset, joints, bw, cloth_topology(cloth_rest, mesh.faces))
        return _lru(self._garments, key, self.keep)

    def _clip(self, mi: int, rest_joints: np.ndarray):
        """``(clip, lead_poses, lead_trans)``: the pair's motion clip and the lead ``dataset make`` would simulate
        before it (what a model's motion history starts from, as a sample's does).  A capture's is read from
        ``cache/motions`` when it is there (keyed by the entry, the dataset's clip length and rate and the body's
        joints), else made from the entry and stored: a capture file is read once per body, and a machine that
        holds the cache trains without the capture files.  A capture file is named by its path relative to the
        config here, not by its bytes: one changed in place needs MOTION_CACHE_VERSION bumped or the cache's
        ``motions/`` removed."""
        from ..io.atomic import atomic_path
        from ..motion.motion import Motion

        m = self.cfg.motions[mi]
        if m.file is None:  # procedural: made in a moment anywhere, never stored (float32, as a stored clip is)
            mo, lead = _motion(m, self.cfg, rest_joints, with_lead=True)
            p32, t32 = np.asarray(mo.poses, np.float32), np.asarray(mo.trans, np.float32)
            return Motion(poses=p32[lead:], trans=t32[lead:], fps=mo.fps, name=m.name), p32[:lead], t32[:lead]
        entry = dataclasses.asdict(m)
        # the file by its path from the config (the same wherever the checkout and ../shared lie; the capture files
        # need not be on a machine that holds the cache)
        entry["file"] = os.path.relpath(m.file, self.cfg.path.parent) if self.cfg.path else m.file.name
        key = repr((entry, self.cfg.fps, self.cfg.seconds, MOTION_CACHE_VERSION)).encode()
        h = hashlib.sha256(key + np.ascontiguousarray(rest_joints, np.float64).tobytes()).hexdigest()[:24]
        p = self.cache / "motions" / f"motion-{h}.npz"
        if p.is_file():
            try:
                with np.load(p) as z:
                    clip = Motion(poses=z["poses"], trans=z["trans"], fps=float(z["fps"]), name=m.name)
                    return clip, z["lead_poses"], z["lead_trans"]
            except (OSError, ValueError, KeyError):
                pass  # a broken entry is made again below
        mo, lead = _motion(m, self.cfg, rest_joints, with_lead=True)
        # stored as float32 (what training reads) and returned as stored: a hit and a miss give the same pair
        poses, trans = np.asarray(mo.poses, np.float32), np.asarray(mo.trans, np.float32)
        p.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(p) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(
                fh,
                poses=poses[lead:],
                trans=trans[lead:],
                lead_poses=poses[:lead],
                lead_trans=trans[:lead],
                fps=np.float64(mo.fps),
            )
        return (
            Motion(poses=poses[lead:], trans=trans[lead:], fps=float(mo.fps), name=m.name),
            poses[:lead],
            trans[:lead],
        )

    def _motion(self, mi: int, bi: int):
        key = (mi, bi)
        if key not in self._motions:
            betas = self.cfg.bodies[bi] or None
            mo, lead_p, lead_t = self._clip(mi, self.body.rest_joints(betas)[0])
            posed = self.body.forward(mo.poses, betas, mo.trans).vertices.astype(np.float32)
            hist = history_inputs(np.concatenate([lead_p, mo.poses]), np.concatenate([lead_t, mo.trans]), mo.fps)
            self._motions[key] = (mo, posed, hist, len(lead_p))
        return _lru(self._motions, key, self.keep)

    def item(self, i: int) -> PairItem:
        p = self.plan[int(i)]
        if p.id not in self._items:
            mesh, a, joints, bw, topo = self._garment(p.garment, p.body)
            mo, posed, hist, lead = self._motion(p.motion, p.body)
            b = np.zeros(self.n_betas)
            betas = np.asarray(self.cfg.bodies[p.body], np.float64)
            b[: betas.size] = betas[: self.n_betas]
            f32 = lambda x: torch.as_tensor(np.asarray(x, np.float32))  # noqa: E731
            self._items[p.id] = PairItem(
                id=p.id,
                features=f32(a.features)[None],
                nbr=torch.as_tensor(a.nbr, dtype=torch.int64),
                mask=torch.as_tensor(a.mask, dtype=torch.bool),
                descriptor=f32(a.descriptor)[None],
                betas=f32(b)[None],
                joints=f32(joints),
                rest=f32(skinned_rest(mesh.vertices, mesh.faces, self.body, betas, self.rest_drape, self._drapes)),
                windows=f32(motion_windows(mo.poses, self.window)),
                history_in=f32(hist),
                lead=lead,
                trans=f32(mo.trans),
                body_weights=f32(bw),
                posed_body=posed,
                topo=topo,
                fps=float(mo.fps),
            )
        return _lru(self._items, p.id, self.keep)


#: bump when the clips PhysicsPairs makes from a motion entry change (old cache entries are then not read)
MOTION_CACHE_VERSION = 4


def _lru(cache: OrderedDict, key, keep: int):
    """``cache[key]``, marked as the newest; the oldest entries past ``keep`` are dropped."""
    cache.move_to_end(key)
    while len(cache) > keep:
        cache.popitem(last=False)
    return cache[key]
