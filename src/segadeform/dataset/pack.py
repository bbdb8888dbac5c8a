"""Dataset packs: a dataset in one read-only file that outlives the machine that simulated it.

A pack is a zip archive (``.sgdpack``) written by ``segadeform dataset pack DIR -o PACK``::

    pack.json                   what the pack holds and what made it (see below)
    configs/NNN.toml            every dataset config the folder was made with
    samples/ID.json, ID.npz     kept samples: the sample's metadata, its arrays (encoded below)
    rejected/ID.json, ID.npz    samples the quality gate rejected (kept so another gate can be applied)

``pack.json``::

    {"format": "segadeform-pack", "version": 1, "frame_step": 1e-4,
     "body": {"name": ..., "sha256": ...},          # the body every sample was simulated on
     "simulator": {"blender": "5.0.1", "bridge": 2}, # Blender's version and the bridge's (SIM_BRIDGE_VERSION)
     "config_digests": [...], "samples": {ID: {"folder", "split", "kind", "motion", "spec", "sha256"}}}

Arrays of a sample (``ID.npz`` inside the archive, LZMA-compressed by the zip):

* ``frames``: positions quantised to ``frame_step`` metres (round to nearest: the rounding error is at
  most ``frame_step / 2`` = 0.05 mm per coordinate), stored as second differences in time (the first
  frame as it is, the second as a difference), then byte-planes split (all low bytes, then the next ...)
  so the compressor sees the small residuals of cloth motion.  Decoding is exact integer arithmetic: the
  error does not grow along the frames.  A sample whose frames are not finite (a rejected one) keeps
  them as float32.
* ``rest``, ``cloth_rest`` float32 (7 significant digits: < 0.1 micrometre on a garment); ``faces`` int32;
  ``poses``, ``trans`` and the lead (``lead_poses``, ``lead_trans``: the motion simulated before the first
  frame, where the sample records it) float32; ``betas`` float64.
* the closest body point and normal of every vertex (training's collision term) are not stored: they
  are recomputed from the body and the frames when the sample is read for training.

A 2,000-vertex, 60-frame sample takes about 0.4 MB (0.39 MB measured on a simulated sample;
``tests/dataset/test_pack.py`` checks the bound of 0.5 MB and the rounding error on simulated cloth).

Packs are only read: :class:`DatasetRoots` (:mod:`.roots`) reads several at once beside dataset
folders, and new samples always go to a folder.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import lzma
import zipfile
import zlib
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..errors import FileFormatError, InputError, file_error
from ..io.atomic import atomic_path
from ..io.npz import check_unpacked
from .store import SAMPLE_FOLDERS, Sample, check_sample, load_sample

#: what reading a damaged member of the archive raises (a flipped byte in an LZMA stream: LZMAError, a traceback
#: in `inspect`, `eval` and `train` before it was caught; a member of another compression: NotImplementedError)
_DAMAGED = (zipfile.BadZipFile, EOFError, OSError, lzma.LZMAError, zlib.error, NotImplementedError)

__all__ = [
    "PACK_SUFFIX",
    "PACK_VERSION",
    "FRAME_STEP",
    "Pack",
    "open_pack",
    "write_pack",
    "encode_frames",
    "decode_frames",
    "PackSummary",
]

PACK_FORMAT = "segadeform-pack"
PACK_VERSION = 1
PACK_SUFFIX = ".sgdpack"
#: metres per quantisation step of the frames: rounding error <= FRAME_STEP / 2 per coordinate
FRAME_STEP = 1e-4


# ------------------------------------------------------------------------------------------------------
# frame codec


def _shuffle(a: np.ndarray) -> np.ndarray:
    """int32 array -> its bytes, plane by plane (all first bytes, then all second bytes ...)."""
    b = np.ascontiguousarray(a, "<i4").view(np.uint8).reshape(-1, 4)
    return np.ascontiguousarray(b.T).reshape(-1)


def _unshuffle(b: np.ndarray, shape) -> np.ndarray:
    n = int(np.prod(shape))
    return np.ascontiguousarray(np.asarray(b, np.uint8).reshape(4, n).T).view("<i4").reshape(shape)


def encode_frames(frames: np.ndarray, step: float = FRAME_STEP) -> dict:
    """Frames ``(T, N, 3)`` -> the arrays that store them (see the module docstring).

    Returns ``{"frames_q": (T*N*3*4,) uint8, "frames_shape": (3,) int64, "frames_step": () float64}``,
    or ``{"frames": float32}`` when the frames are not finite or do not fit 32-bit steps.
    """
    x = np.asarray(frames, np.float64)
    if x.ndim != 3 or x.shape[2] != 3:
        raise InputError("frames must be (T, N, 3)", got=x.shape)
    if not (np.isfinite(step) and step > 0):
        raise InputError("frame step must be positive", got=step)
    if not np.isfinite(x).all() or np.abs(x).max(initial=0.0) / step > 2.0**29:
        return {"frames": x.astype(np.float32)}
    q = np.rint(x / step).astype(np.int64)
    r = q.copy()
    if len(q) >= 2:
        r[1] = q[1] - q[0]
    if len(q) >= 3:
        r[2:] = q[2:] - 2 * q[1:-1] + q[:-2]
    if np.abs(r).max(initial=0) >= 2**31:
        return {"frames": x.astype(np.float32)}
    return {
        "frames_q": _shuffle(r.astype(np.int32)),
        "frames_shape": np.array(q.shape, np.int64),
        "frames_step": np.float64(step),
    }


def decode_frames(arrays: dict) -> np.ndarray:
    """The inverse of :func:`encode_frames`: ``(T, N, 3)`` float32."""
    if "frames" in arrays:
        return np.asarray(arrays["frames"], np.float32)
    shape = tuple(int(s) for s in arrays["frames_shape"])
    if len(shape) != 3 or shape[2] != 3 or min(shape) < 0:
        raise InputError("frames_shape must be (T, N, 3)", got=shape)
    r = _unshuffle(arrays["frames_q"], shape).astype(np.int64)
    if len(r) >= 2:
        d = np.cumsum(r[1:], axis=0)  # first differences q_t - q_{t-1}, t >= 1
        q = np.concatenate([r[:1], r[:1] + np.cumsum(d, axis=0)])
    else:
        q = r
    return (q * float(arrays["frames_step"])).astype(np.float32)


# ------------------------------------------------------------------------------------------------------
# writing


def _sample_bytes(s: Sample, step: float) -> bytes:
    arrays = {
        "rest": np.asarray(s.rest, np.float32),
        "faces": np.asarray(s.faces, np.int32),
        "betas": np.asarray(s.betas, np.float64),
        "poses": np.asarray(s.poses, np.float32),
        "trans": np.asarray(s.trans, np.float32),
        **encode_frames(s.frames, step),
    }
    if s.cloth_rest is not None:
        arrays["cloth_rest"] = np.asarray(s.cloth_rest, np.float32)
    if s.lead_poses is not None and s.lead_trans is not None:
        arrays["lead_poses"] = np.asarray(s.lead_poses, np.float32)
        arrays["lead_trans"] = np.asarray(s.lead_trans, np.float32)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@dataclasses.dataclass(frozen=True)
class PackSummary:
    path: Path
    samples: int  # kept samples packed
    rejected: int  # rejected samples packed
    skipped: int  # samples left out because a pack given in ``skip`` holds them already
    bytes: int


def write_pack(
    folder,
    out,
    *,
    body,
    skip: Iterable[Pack] = (),
    include_rejected: bool = True,
    step: float = FRAME_STEP,
    progress=None,
) -> PackSummary:
    """Pack the dataset folder ``folder`` into the new file ``out`` (atomically; never over a file).

    Args:
        body: the :class:`~segadeform.body.BodyModel` the dataset was simulated on (its hash is recorded).
        skip: packs whose samples are left out (a pack made later holds only what is new).
        include_rejected: pack the gate's rejected samples too (another gate can then be applied).
    """
    from ..body.identity import body_label
    from ..physics.blender import SIM_BRIDGE_VERSION

    root = Path(folder)
    out = Path(out)
    if not (root / "samples").is_dir():
        raise InputError("not a dataset folder (no samples/ in it)", path=root)
    if out.exists():
        raise InputError("the pack exists already; packs are never overwritten", path=out, expected="a new file name")
    if out.suffix != PACK_SUFFIX:
        raise InputError("a pack's name ends in .sgdpack", path=out, got=out.suffix or "no suffix")
    have = set()
    for p in skip:
        have |= set(p.entries)
    entries, blender_versions, digests = {}, set(), set()
    # the body the samples were simulated on, checked before anything is compressed (their records)
    bodies = set()
    for folder_name in SAMPLE_FOLDERS if include_rejected else ("samples",):
        for meta_p in sorted((root / folder_name).glob("*.json")) if (root / folder_name).is_dir() else []:
            try:
                rec = json.loads(meta_p.read_text())
            except (OSError, ValueError):
                continue  # (load_sample names an unreadable record when the sample is packed)
            if isinstance(rec, dict) and rec.get("body_sha256"):
                bodies.add(str(rec["body_sha256"]))
    label = body_label(body)
    if len(bodies) > 1:
        raise InputError(
            "the dataset mixes samples of several bodies; pack each apart",
            path=root,
            got=", ".join(sorted(b[:12] for b in bodies)),
        )
    if bodies and bodies != {label["sha256"]}:  # the head must say the body the samples were made on
        raise InputError(
            "the samples were simulated on another body than the one given (--body)",
            path=root,
            expected=f"the body of sha256 {next(iter(bodies))[:12]}",
            got=f"{label['name'] or 'a body'} (sha256 {label['sha256'][:12]})",
        )
    counts = {"samples": 0, "rejected": 0}
    skipped = 0
    with atomic_path(out) as tmp:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_LZMA) as z:
            for folder_name in SAMPLE_FOLDERS if include_rejected else ("samples",):
                d = root / folder_name
                for meta_p in sorted(d.glob("*.json")) if d.is_dir() else []:
                    sid = meta_p.stem
                    if not (d / f"{sid}.npz").is_file():
                        continue  # rejected before arrays were kept
                    if sid in have:
                        skipped += 1
                        continue
                    s = load_sample(root, sid, folder_name)
                    data = _sample_bytes(s, step)
                    meta = json.dumps(s.meta, indent=1, sort_keys=True).encode("utf-8")
                    z.writestr(f"{folder_name}/{sid}.npz", data)
                    z.writestr(f"{folder_name}/{sid}.json", meta)
                    m = s.meta
                    if m.get("blender"):
                        blender_versions.add(str(m["blender"]))
                    if m.get("config_digest"):
                        digests.add(str(m["config_digest"]))
                    entries[sid] = {
                        "folder": folder_name,
                        "split": m.get("split"),
                        "kind": m.get("kind"),
                        "garment": m.get("garment"),
                        "motion": m.get("motion"),
                        "spec": m.get("spec"),
                        "sim_bridge": m.get("sim_bridge", 1),
                        "sha256": hashlib.sha256(data).hexdigest(),
                    }
                    counts[folder_name] += 1
                    if progress is not None:
                        progress(sid)
            if not entries:  # a pack of nothing claims no simulator and broke every folder of packs it joined
                raise InputError(
                    "nothing to pack: no file is written",
                    path=root,
                    expected="samples that dataset make kept or rejected"
                    + (", not already in the packs given (--skip)" if skipped else ""),
                    got=f"{skipped} samples, all in the packs given" if skipped else "no samples",
                )
            for cfg in sorted((root / "configs").glob("*.toml")) if (root / "configs").is_dir() else []:
                z.write(cfg, f"configs/{cfg.name}")
            if len(blender_versions) > 1:
                raise InputError(
                    "the dataset mixes samples of several Blender versions; pack each apart",
                    path=root,
                    got=", ".join(sorted(blender_versions)),
                )
            bridges = {e["sim_bridge"] for e in entries.values()}
            if len(bridges) > 1:
                raise InputError(
                    "the dataset mixes samples of several simulator bridge versions", path=root, got=sorted(bridges)
                )
            head = {
                "format": PACK_FORMAT,
                "version": PACK_VERSION,
                "frame_step": step,
                "body": label,
                "simulator": {
                    "blender": next(iter(blender_versions), None),
                    "bridge": next(iter(bridges), SIM_BRIDGE_VERSION),
                },
                "config_digests": sorted(digests),
                "samples": entries,
            }
            z.writestr("pack.json", json.dumps(head, indent=1, sort_keys=True))
    return PackSummary(
        path=out, samples=counts["samples"], rejected=counts["rejected"], skipped=skipped, bytes=out.stat().st_size
    )


# ------------------------------------------------------------------------------------------------------
# reading


class Pack:
    """A pack opened for reading (never written).  ``entries``: id -> its line of ``pack.json``."""

    def __init__(self, path) -> None:
        self.path = Path(path)
        try:
            self._zip = zipfile.ZipFile(self.path, "r")
        except OSError as e:
            raise file_error(e, self.path, "dataset pack") from None
        except zipfile.BadZipFile:
            # a file that starts as a zip archive and has no directory at its end was cut short (a copy or a download
            # that stopped): said so, not "not a pack" (a researcher's trial)
            try:
                with open(self.path, "rb") as fh:
                    starts_as_zip = fh.read(4) == b"PK\x03\x04"
            except OSError:
                starts_as_zip = False
            if starts_as_zip:
                raise FileFormatError(
                    "the dataset pack is truncated or damaged (its zip directory is missing: a copy cut short?)",
                    path=self.path,
                    expected="the whole file, as `segadeform dataset pack` wrote it",
                ) from None
            raise FileFormatError("not a dataset pack (not a zip archive)", path=self.path) from None
        try:
            head = json.loads(self._read("pack.json"))
        except FileFormatError:
            raise
        except KeyError:
            raise FileFormatError("not a dataset pack (no pack.json)", path=self.path) from None
        except (ValueError, *_DAMAGED) as e:
            raise FileFormatError(f"pack.json is unreadable ({e})", path=self.path) from None
        if not isinstance(head, dict) or head.get("format") != PACK_FORMAT:
            raise FileFormatError(
                "not a dataset pack",
                path=self.path,
                expected=PACK_FORMAT,
                got=head.get("format") if isinstance(head, dict) else type(head).__name__,
            )
        if head.get("version") != PACK_VERSION:
            raise FileFormatError(
                "unsupported pack version", path=self.path, expected=PACK_VERSION, got=head.get("version")
            )
        ent = head.get("samples")
        if not isinstance(ent, dict) or not all(
            isinstance(v, dict) and v.get("folder") in SAMPLE_FOLDERS for v in ent.values()
        ):
            raise FileFormatError("pack.json lists no valid samples", path=self.path)
        self.head = head
        self.entries: dict = ent

    def _read(self, name: str) -> bytes:
        """Member ``name`` of the pack, refused when it unpacks to far more than its compressed size (a security
        review: a 455 KB pack whose pack.json unpacked to 3 GiB)."""
        check_unpacked(self._zip.getinfo(name), self.path, name)
        return self._zip.read(name)

    # what made it
    @property
    def body_sha256(self) -> str | None:
        return (self.head.get("body") or {}).get("sha256")

    @property
    def simulator(self) -> dict:
        return dict(self.head.get("simulator") or {})

    def ids(self, folder: str = "samples") -> list[str]:
        return sorted(k for k, v in self.entries.items() if v["folder"] == folder)

    def read_meta(self, sid: str) -> dict:
        e = self._entry(sid)
        try:
            return json.loads(self._read(f"{e['folder']}/{sid}.json"))
        except FileFormatError:
            raise
        except (KeyError, ValueError, *_DAMAGED) as err:
            raise FileFormatError(f"sample {sid}'s metadata is unreadable ({err})", path=self.path) from None

    def load(self, sid: str) -> Sample:
        e = self._entry(sid)
        try:
            data = self._read(f"{e['folder']}/{sid}.npz")
        except (KeyError, *_DAMAGED) as err:
            raise FileFormatError(f"sample {sid} is unreadable ({err})", path=self.path) from None
        if hashlib.sha256(data).hexdigest() != e.get("sha256"):
            raise FileFormatError(
                f"sample {sid} does not match its recorded SHA-256 (the pack is damaged)", path=self.path
            )
        try:
            with zipfile.ZipFile(io.BytesIO(data)) as inner:  # the sample's own arrays: no bomb inside either
                for info in inner.infolist():
                    check_unpacked(info, self.path, f"sample {sid}'s {info.filename}")
            z = dict(np.load(io.BytesIO(data), allow_pickle=False))
            frames = decode_frames(z)
        except (ValueError, KeyError, OSError, InputError) as err:
            raise FileFormatError(f"sample {sid}'s arrays are unreadable ({err})", path=self.path) from None
        missing = [k for k in ("rest", "faces", "betas", "poses", "trans") if k not in z]
        if missing:
            raise FileFormatError(f"sample {sid} lacks {missing[0]!r}", path=self.path)
        lead = "lead_poses" in z and "lead_trans" in z
        if not np.issubdtype(z["faces"].dtype, np.integer):
            raise FileFormatError(
                f"sample {sid} array 'faces' is not integer", path=self.path, got=str(z["faces"].dtype)
            )
        s = Sample(
            id=sid,
            rest=z["rest"].astype(np.float64),
            faces=z["faces"].astype(np.int64),
            betas=z["betas"],
            poses=z["poses"].astype(np.float64),
            trans=z["trans"].astype(np.float64),
            frames=frames,
            meta=self.read_meta(sid),
            cloth_rest=z["cloth_rest"].astype(np.float64) if "cloth_rest" in z else None,
            lead_poses=z["lead_poses"].astype(np.float64) if lead else None,
            lead_trans=z["lead_trans"].astype(np.float64) if lead else None,
        )
        return check_sample(s, self.path, f"sample {sid}", finite_frames=e["folder"] == "samples")

    def configs(self) -> list[str]:
        return sorted(n for n in self._zip.namelist() if n.startswith("configs/") and n.endswith(".toml"))

    def _entry(self, sid: str) -> dict:
        e = self.entries.get(sid)
        if e is None:
            raise InputError(f"sample {sid} is not in this pack", path=self.path)
        return e

    def close(self) -> None:
        self._zip.close()

    def __repr__(self) -> str:
        return f"Pack({str(self.path)!r}, {len(self.entries)} samples)"


def open_pack(path) -> Pack:
    return Pack(path)
