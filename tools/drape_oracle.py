"""How much of the non-learned prior's error is a static correction, and can the garment's rest geometry alone
predict it?  (issue #27: where a learned model has room to beat ``lbs-smooth``.)

For every kept sample of DATASET (a folder, pack or several roots):

* ``prior``: the vertex error of ``lbs-smooth`` (cm, mean over frames and vertices);
* ``oracle``: the same after adding the sample's own *static* rest-space correction: each vertex's skinned
  residual mapped back through its LBS linear part and averaged over the frames, ``D = mean_t M_t^-1 (gt_t - x_t)``
  (``M_t = sum_j w_j R_j(t)``), then skinned again: the best any per-sample blend shape can do;
* ``mlp``: ``D`` predicted by a small MLP from per-vertex rest geometry (position, normal, signed distance to the
  body at rest), trained on the training split's ``D`` and applied to the other splits;
* ``others``: the mean ``D`` of the *other* samples of the same garment design and body (their other motions;
  samples alone in their group are left out of this column's means): what a predictor that knew the garment's
  drape on this body exactly, but not the motion, could do with one static correction.

    .venv/bin/python tools/drape_oracle.py data/continuum [--steps 3000] [--seed 0]

Prints one line per sample and the means per split.  CPU only; a few minutes for a few dozen samples.
"""

from __future__ import annotations

import argparse

import numpy as np


def sample_rows(dataset, body):
    from segadeform.body.cloth import rest_signed_distance
    from segadeform.body.transfer import garment_weights, skin_garment
    from segadeform.dataset.roots import as_roots
    from segadeform.geometry.mesh_ops import vertex_normals

    roots = as_roots(dataset)
    for split in ("train", "val", "test"):
        for sid in roots.ids(split):
            s = roots.load(sid)
            betas = s.betas if s.betas.size else None
            w = garment_weights(s.rest, s.faces, body, betas, "smooth")
            lin = body.forward(s.poses, betas, s.trans).transforms[:, :, :3, :3]  # (T, S, 3, 3)
            m = np.einsum("ns,tsij->tnij", w, lin)  # each vertex's LBS linear part (T, N, 3, 3)
            x = skin_garment(s.rest, w, body, s.poses, betas, s.trans)
            gt = s.frames.astype(np.float64)
            d = np.linalg.solve(m, (gt - x)[..., None])[..., 0].mean(0)  # (N, 3) rest-space static correction
            sd = rest_signed_distance(s.rest, body.shaped_vertices(betas)[0], body.faces)
            feats = np.concatenate([s.rest, vertex_normals(s.rest, s.faces), sd[:, None]], 1).astype(np.float32)
            yield dict(id=sid, split=split, type=s.meta.get("type", "?"), m=m, x=x, gt=gt, d=d, feats=feats)


def error_cm(x, gt) -> float:
    return float(100 * np.linalg.norm(x - gt, axis=2).mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", nargs="+")
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    import torch

    from segadeform.body.model import default_body_path, load_body

    torch.manual_seed(a.seed)
    rows = list(sample_rows(a.dataset, load_body(default_body_path())))
    train = [r for r in rows if r["split"] == "train"]
    if not train:
        raise SystemExit("no kept training samples in " + " ".join(a.dataset))
    xs = torch.tensor(np.concatenate([r["feats"] for r in train]))
    ys = torch.tensor(np.concatenate([r["d"] for r in train]).astype(np.float32))
    net = torch.nn.Sequential(
        *(torch.nn.Linear(xs.shape[1], 64), torch.nn.SiLU()),
        *(torch.nn.Linear(64, 64), torch.nn.SiLU()),
        torch.nn.Linear(64, 3),
    )
    opt = torch.optim.AdamW(net.parameters(), 3e-3, weight_decay=1e-4)
    for _ in range(a.steps):
        i = torch.randint(0, len(xs), (4096,))
        loss = (net(xs[i]) - ys[i]).norm(dim=1).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    groups: dict = {}
    for r in rows:
        groups.setdefault(tuple(r["id"].split("__")[:2]), []).append(r)
    table, others = {}, {}
    for r in rows:
        with torch.no_grad():
            dp = net(torch.tensor(r["feats"])).numpy().astype(np.float64)
        e = (
            error_cm(r["x"], r["gt"]),
            error_cm(r["x"] + np.einsum("tnij,nj->tni", r["m"], r["d"]), r["gt"]),
            error_cm(r["x"] + np.einsum("tnij,nj->tni", r["m"], dp), r["gt"]),
        )
        table.setdefault(r["split"], []).append(e)
        name = f"{r['split']:5s} {r['id'][:40]:40s} {r['type']:10s}"
        rest = [o["d"] for o in groups[tuple(r["id"].split("__")[:2])] if o is not r]
        line = f"{name} prior {e[0]:6.2f} oracle {e[1]:6.2f} mlp {e[2]:6.2f}"
        if rest:
            eo = error_cm(r["x"] + np.einsum("tnij,nj->tni", r["m"], np.mean(rest, axis=0)), r["gt"])
            others.setdefault(r["split"], []).append((e[0], e[1], eo))
            line += f" others {eo:6.2f}"
        print(line)
    for split, es in table.items():
        p, o, m = np.mean(es, axis=0)
        print(
            f"{split:5s} ({len(es)}): prior {p:.3f} cm, static oracle {o:.3f} ({100 * (o / p - 1):+.1f} %), "
            f"rest-geometry MLP {m:.3f} ({100 * (m / p - 1):+.1f} %)"
        )
    for split, es in others.items():
        p, o, g = np.mean(es, axis=0)
        print(
            f"{split:5s} ({len(es)} with another motion of the same design and body): prior {p:.3f} cm, static "
            f"oracle {o:.3f} ({100 * (o / p - 1):+.1f} %), the other motions' static correction {g:.3f} "
            f"({100 * (g / p - 1):+.1f} %)"
        )


if __name__ == "__main__":
    main()
