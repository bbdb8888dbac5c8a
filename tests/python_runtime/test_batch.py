"""`segadeform batch`: the jobs file, every garment x motion run once and committed, resumed, refused
when a finished job's spec changed; outputs in a folder or at a URL (fsspec)."""

from __future__ import annotations

import json

import pytest

from segadeform.cli.main import main
from segadeform.errors import FileFormatError, InputError
from segadeform.io import read_pc2, read_sequence
from segadeform.runtime.batch import batch_jobs, load_batch, run_batch

from ..conftest import SAMPLES, leftovers

JOBS = f"""
[batch]
output = "out"
effects = "lbs,collisions"

[[garments]]
mesh = "{SAMPLES / "garments" / "skirt.obj"}"

[[garments]]
name = "big-skirt"
mesh = "{SAMPLES / "garments" / "skirt.obj"}"
betas = [0.1]

[[motions]]
file = "{SAMPLES / "motions" / "walk.npz"}"
frames = "0:6"

[[motions]]
kind = "dance"
seconds = 0.3
"""
IDS = ["big-skirt__dance", "big-skirt__walk", "skirt__dance", "skirt__walk"]


def jobs_file(tmp_path, text=JOBS, name="jobs.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_jobs_file_makes_every_garment_x_motion(tmp_path):
    cfg = load_batch(jobs_file(tmp_path))
    assert cfg.output == str(tmp_path / "out") and cfg.effects.label() == "lbs+collisions"
    jobs = batch_jobs(cfg)
    assert sorted(j.id for j in jobs) == IDS and {j.output_name for j in jobs} == {f"{i}.pc2" for i in IDS}
    assert len({j.spec for j in jobs}) == 4
    assert batch_jobs(load_batch(jobs_file(tmp_path, name="again.toml")))[0].spec == jobs[0].spec


@pytest.mark.parametrize(
    "edit, msg",
    [
        (("[batch]", "[batch]\nspeed = 1"), "unknown key batch.speed"),
        (('kind = "dance"', 'kind = "moonwalk"'), "not a motion kind"),
        (('kind = "dance"', f'kind = "dance"\nfile = "{SAMPLES / "motions" / "walk.npz"}"'), "exactly one"),
        (('name = "big-skirt"', 'name = "skirt"'), "used twice"),
        (('name = "big-skirt"', 'name = "a__b"'), "not usable in a file name"),
        (('effects = "lbs,collisions"', 'effects = "fire"'), "unknown effect"),
        (('frames = "0:6"', 'frames = "6:0"'), "0 <= A < B"),
        (("[batch]", '[batch]\nformat = "gif"'), "not an output format"),
        (("betas = [0.1]", "betas = 0.1"), "wrong type"),
        (
            ('effects = "lbs,collisions"', 'quality = "turbo"'),
            r"batch.quality: unknown quality preset.*fast \| balanced",
        ),
        (('effects = "lbs,collisions"', 'quality = "fast"\neffects = "lbs"'), "batch.quality: a quality preset takes"),
        (('effects = "lbs,collisions"', 'effects = "lbs"\ncollision_margin = 0.01'), "neither collisions nor the cl"),
        (("[batch]", "[batch]\ncloth_iterations = 8"), "batch.cloth_iterations is set but the cloth stage is off"),
        (('effects = "lbs,collisions"', 'quality = "best"\ncloth_iterations = 0'), "cloth iterations must be"),
        (
            ('effects = "lbs,collisions"', "collision_margin = 1.5"),
            r"jobs.toml:\d+: batch.collision_margin: .*\[0, 1\)",
        ),
    ],
)
def test_bad_jobs_files(tmp_path, edit, msg):
    assert edit[0] in JOBS
    with pytest.raises(FileFormatError, match=msg) as e:
        load_batch(jobs_file(tmp_path, JOBS.replace(edit[0], edit[1], 1)))
    assert "jobs.toml" in str(e.value)


def test_a_jobs_file_takes_a_preset_a_margin_and_cloth_knobs_as_run_does(tmp_path, capsys):
    """`quality`, `collision_margin` and `cloth_<knob>` in [batch] are `run --quality --collision-margin --cloth`
    (a new user's trial: `unknown key batch.quality`): a job's frames are those of the same `run`, and its spec
    changes with them (a finished job is not taken for another setting's)."""
    text = JOBS.replace(
        'effects = "lbs,collisions"', 'quality = "best"\ncollision_margin = 0.006\ncloth_iterations = 2'
    )
    cfg = load_batch(jobs_file(tmp_path, text))
    assert cfg.effects.cloth and cfg.effects.collision_margin == 0.006 and cfg.effects.cloth_settings.iterations == 2
    plain = batch_jobs(
        load_batch(jobs_file(tmp_path, JOBS.replace('effects = "lbs,collisions"', 'quality = "best"'), "plain.toml"))
    )
    assert {j.id: j.spec for j in batch_jobs(cfg)}.keys() == {j.id: j.spec for j in plain}.keys()
    assert not {j.spec for j in batch_jobs(cfg)} & {j.spec for j in plain}
    text = text.replace('[[garments]]\nname = "big-skirt"', '[[unused]]\nname = "big-skirt"').split("[[unused]]")[0]
    jf = jobs_file(
        tmp_path, text + f'[[motions]]\nfile = "{SAMPLES / "motions" / "walk.npz"}"\nframes = "0:4"\n', "one.toml"
    )
    assert main(["batch", str(jf)]) == 0
    rec = json.loads((tmp_path / "out" / "jobs" / "skirt__walk.json").read_text())
    assert rec["effects"] == "lbs+dynamics+wrinkles+cloth(iterations=2)"
    args = ["--quality", "best", "--collision-margin", "0.006", "--cloth", "iterations=2", "--frames", "0:4"]
    g, m = str(SAMPLES / "garments" / "skirt.obj"), str(SAMPLES / "motions" / "walk.npz")
    assert main(["run", "--garment", g, "--motion", m, *args, "-o", str(tmp_path / "one.pc2")]) == 0
    assert (tmp_path / "one.pc2").read_bytes() == (tmp_path / "out" / "skirt__walk.pc2").read_bytes()


def test_a_jobs_file_names_its_output_units_as_run_does(tmp_path):
    """`units` in [batch] is `run --output-units`: a job's bytes are that run's; a metre job keeps the spec it had
    before units existed (a finished batch resumes), a centimetre one has another."""
    one = (
        JOBS.split('[[garments]]\nname = "big-skirt"')[0]
        + f'[[motions]]\nfile = "{SAMPLES / "motions" / "walk.npz"}"\n'
    )
    one += 'frames = "0:4"\n'
    metres = batch_jobs(load_batch(jobs_file(tmp_path, one, "m.toml")))
    assert (
        batch_jobs(load_batch(jobs_file(tmp_path, one.replace("[batch]", '[batch]\nunits = "m"'), "m2.toml")))[0].spec
        == metres[0].spec
    )
    jf = jobs_file(tmp_path, one.replace("[batch]", '[batch]\nunits = "cm"'), "cm.toml")
    cfg = load_batch(jf)
    assert cfg.units == 0.01 and batch_jobs(cfg)[0].spec != metres[0].spec
    assert main(["batch", str(jf)]) == 0
    g, m = str(SAMPLES / "garments" / "skirt.obj"), str(SAMPLES / "motions" / "walk.npz")
    args = ["--effects", "lbs,collisions", "--frames", "0:4", "--output-units", "cm"]
    assert main(["run", "--garment", g, "--motion", m, *args, "-o", str(tmp_path / "one.pc2")]) == 0
    assert (tmp_path / "one.pc2").read_bytes() == (tmp_path / "out" / "skirt__walk.pc2").read_bytes()
    with pytest.raises(FileFormatError, match=r"cm2.toml:\d+: unknown batch.units"):
        load_batch(jobs_file(tmp_path, one.replace("[batch]", '[batch]\nunits = "furlongs"'), "cm2.toml"))


def test_batch_runs_resumes_and_refuses_a_changed_job(tmp_path, capsys):
    jf = jobs_file(tmp_path)
    assert main(["batch", str(jf), "-j", "2"]) == 0
    assert "4 jobs, 0 already done, 4 made" in capsys.readouterr().out
    out = tmp_path / "out"
    assert sorted(p.stem for p in out.glob("*.pc2")) == IDS
    assert sorted(p.stem for p in (out / "jobs").glob("*.json")) == IDS and leftovers(out) == []
    rec = json.loads((out / "jobs" / "skirt__walk.json").read_text())
    assert rec["frames"] == 6 and rec["files"] == ["skirt__walk.pc2"] and rec["effects"] == "lbs+collisions"
    assert read_pc2(out / "skirt__walk.pc2").frames.shape[0] == 6
    # the same as one `segadeform run` of that garment and motion
    assert (
        main(
            [
                "run",
                "--garment",
                str(SAMPLES / "garments" / "skirt.obj"),
                "--motion",
                str(SAMPLES / "motions" / "walk.npz"),
                "--frames",
                "0:6",
                "--effects",
                "lbs,collisions",
                "-o",
                str(tmp_path / "one.pc2"),
            ]
        )
        == 0
    )
    assert (tmp_path / "one.pc2").read_bytes() == (out / "skirt__walk.pc2").read_bytes()
    # resumed: a job whose record is missing is run again, the others skipped
    (out / "jobs" / "skirt__dance.json").unlink()
    before = (out / "skirt__walk.pc2").stat().st_mtime_ns
    capsys.readouterr()
    assert main(["batch", str(jf)]) == 0
    assert "4 jobs, 3 already done, 1 made" in capsys.readouterr().out
    assert (out / "skirt__walk.pc2").stat().st_mtime_ns == before
    # a finished job given another meaning under its name stops the run before anything runs
    changed = jobs_file(tmp_path, JOBS.replace('frames = "0:6"', 'frames = "0:8"'), "changed.toml")
    with pytest.raises(InputError, match="another spec"):
        run_batch(load_batch(changed))


def test_batch_to_a_url_in_frame_folders(tmp_path):
    fsspec = pytest.importorskip("fsspec")
    jf = jobs_file(
        tmp_path, JOBS.replace('output = "out"', 'output = "memory://segadeform-batch-test/out"\nformat = "obj-seq"')
    )
    s = run_batch(load_batch(jf), limit=1)
    assert (s.planned, s.skipped, s.made) == (4, 0, 1)
    fs = fsspec.filesystem("memory")
    jid = s.records[0]["id"]
    names = sorted(p.rsplit("/", 1)[1] for p in fs.find(f"/segadeform-batch-test/out/{jid}"))
    assert len(names) == s.records[0]["frames"] and all(n.endswith(".obj") for n in names)
    assert fs.isfile(f"/segadeform-batch-test/out/jobs/{jid}.json")
    assert not [p for p in fs.find("/segadeform-batch-test") if ".tmp-" in p]
    local = tmp_path / "copy"
    fs.get(f"/segadeform-batch-test/out/{jid}", str(local), recursive=True)
    assert read_sequence(local).shape[0] == s.records[0]["frames"]


def test_a_job_whose_garment_is_refused_does_not_stop_the_others(tmp_path, capsys):
    """One garment off the body stopped the whole batch, naming neither the job nor the jobs file's entry, and
    `batch --force` was refused the same way.  Now the other jobs are made, the failed one is named (and made by a
    later run once fixed, or with --force), and the exit status says that not everything was made."""
    import numpy as np

    from segadeform.io import read_mesh, write_obj

    m = read_mesh(SAMPLES / "garments" / "skirt.obj")
    write_obj(tmp_path / "cm.obj", type(m)(vertices=m.vertices * 100, faces=m.faces))  # in cm: off the body
    text = JOBS.replace(
        f'mesh = "{SAMPLES / "garments" / "skirt.obj"}"\nbetas = [0.1]', f'mesh = "{tmp_path / "cm.obj"}"'
    )
    assert text != JOBS
    jf = jobs_file(tmp_path, text)
    assert main(["batch", str(jf), "-j", "1"]) == 1
    cap = capsys.readouterr()
    assert "4 jobs, 0 already done, 2 made, 2 failed" in cap.out
    assert "2 of 4 jobs failed (first: job big-skirt__" in cap.err and "garment 'big-skirt'" in cap.err
    assert "it does once read in cm" in cap.err and "--force" in cap.err
    done = sorted(p.stem for p in (tmp_path / "out" / "jobs").glob("*.json"))
    assert done == ["skirt__dance", "skirt__walk"]
    assert main(["batch", str(jf), "-j", "1", "--force"]) == 0  # the refused ones, accepted
    assert "4 jobs, 2 already done, 2 made -> " in capsys.readouterr().out
    assert np.isfinite(read_pc2(tmp_path / "out" / "big-skirt__walk.pc2").frames).all()


def test_a_failed_batch_offers_force_only_for_what_force_accepts(tmp_path, capsys):
    """A job refused for its garment file's contents (no face with an area) is not one --force makes: the summary
    no longer ends "or pass --force" (a new user's trial); a garment off the body still is (test above)."""
    (tmp_path / "flat.obj").write_text("v 0 1.2 0.15\nv 0.1 1.2 0.15\nv 0.2 1.2 0.15\nf 1 2 3\n")
    text = JOBS.replace(
        f'mesh = "{SAMPLES / "garments" / "skirt.obj"}"\nbetas = [0.1]', f'mesh = "{tmp_path / "flat.obj"}"'
    )
    assert text != JOBS
    assert main(["batch", str(jobs_file(tmp_path, text)), "-j", "1"]) == 1
    err = capsys.readouterr().err
    assert "2 of 4 jobs failed" in err and "no face with an area" in err
    assert "--force" not in err.splitlines()[-1] and "fix the jobs file, then run again" in err


ONE = f"""
[batch]
output = "out"
effects = "lbs"

[[garments]]
mesh = "{SAMPLES / "garments" / "skirt.obj"}"

[[motions]]
file = "{SAMPLES / "motions" / "walk.npz"}"
frames = "0:4"
"""
TWO = ONE + '\n[[motions]]\nkind = "dance"\nseconds = 0.2\n'


def test_batch_never_writes_over_a_file_it_did_not_write_and_makes_a_job_again_when_its_output_is_gone(
    tmp_path, capsys
):
    """A pipeline TD's trial: a jobs file grown by a motion whose output name holds the studio's own file wrote over
    it, and a finished job whose output was deleted or truncated stayed "already done".  Now the file in the way is
    refused before anything runs (one line, exit 1, the file intact), an output that is gone is made again (the same
    bytes), one whose size changed is refused (never written over), and a killed attempt's output (its marker there)
    or one the folder's manifest lists (its record removed to have it made again) is the batch's own to replace."""
    out = tmp_path / "out"
    assert main(["batch", str(jobs_file(tmp_path, ONE))]) == 0
    walk = (out / "skirt__walk.pc2").read_bytes()
    jf = jobs_file(tmp_path, TWO)
    (out / "skirt__dance.pc2").write_text("MINE")
    capsys.readouterr()
    assert main(["batch", str(jf)]) == 1
    err = capsys.readouterr().err
    assert "skirt__dance.pc2" in err and "did not write" in err and len(err.strip().splitlines()) == 1, err
    assert (out / "skirt__dance.pc2").read_text() == "MINE" and not (out / "jobs" / "skirt__dance.json").exists()
    (out / "skirt__dance.pc2").unlink()
    assert main(["batch", str(jf)]) == 0
    assert "2 jobs, 1 already done, 1 made" in capsys.readouterr().out
    rec = json.loads((out / "jobs" / "skirt__dance.json").read_text())
    assert rec["sizes"] == {"skirt__dance.pc2": (out / "skirt__dance.pc2").stat().st_size}
    assert not list((out / "jobs").glob("*.partial"))
    # a finished job's output deleted: made again, the same bytes
    (out / "skirt__walk.pc2").unlink()
    assert main(["batch", str(jf)]) == 0
    assert "2 jobs, 1 already done, 1 made" in capsys.readouterr().out
    assert (out / "skirt__walk.pc2").read_bytes() == walk
    # truncated (or edited): refused, left as it is
    with open(out / "skirt__walk.pc2", "r+b") as fh:
        fh.truncate(100)
    assert main(["batch", str(jf)]) == 1
    err = capsys.readouterr().err
    assert "skirt__walk.pc2 (100 bytes, written" in err and "never writes over" in err, err
    assert (out / "skirt__walk.pc2").stat().st_size == 100
    (out / "skirt__walk.pc2").unlink()
    assert main(["batch", str(jf)]) == 0 and (out / "skirt__walk.pc2").read_bytes() == walk
    capsys.readouterr()
    # a job killed between its output and its record: with its marker the output is the batch's, made again ...
    (out / "jobs" / "skirt__walk.json").unlink()
    (out / "jobs" / "skirt__walk.partial").write_text('["skirt__walk.pc2"]')
    assert main(["batch", str(jf)]) == 0
    assert "2 jobs, 1 already done, 1 made" in capsys.readouterr().out
    assert (out / "skirt__walk.pc2").read_bytes() == walk and not (out / "jobs" / "skirt__walk.partial").exists()
    # ... a record removed to have the job made again: the folder's manifest says the output is the batch's ...
    (out / "jobs" / "skirt__walk.json").unlink()
    assert main(["batch", str(jf)]) == 0
    assert "2 jobs, 1 already done, 1 made" in capsys.readouterr().out
    # ... but a file of the user's put there since is nobody's the batch knows: refused
    (out / "jobs" / "skirt__walk.json").unlink()
    (out / "skirt__walk.pc2").write_text("MINE")
    assert main(["batch", str(jf)]) == 1
    assert "did not write (first: skirt__walk.pc2)" in capsys.readouterr().err
    assert (out / "skirt__walk.pc2").read_text() == "MINE"


def test_a_folder_with_a_jobs_folder_is_not_taken_for_a_batch_s_own(tmp_path, capsys):
    """Any folder with a jobs/ sub-folder was continued as a batch folder made before manifests, writing over the
    files in it; only one whose jobs/ holds job records and whose other names are job outputs is."""
    out = tmp_path / "out"
    (out / "jobs").mkdir(parents=True)
    (out / "skirt__walk.pc2").write_text("MINE")
    assert main(["batch", str(jobs_file(tmp_path, ONE))]) == 1
    assert "did not write" in capsys.readouterr().err and (out / "skirt__walk.pc2").read_text() == "MINE"
    (out / "skirt__walk.pc2").unlink()
    (out / "jobs" / "render_farm.txt").write_text("queue 7")
    assert main(["batch", str(jobs_file(tmp_path, ONE))]) == 1
    assert "did not write" in capsys.readouterr().err
    # an earlier batch's folder without a manifest (records and outputs only) is continued
    (out / "jobs" / "render_farm.txt").unlink()
    (out / "jobs").rmdir()
    out.rmdir()
    assert main(["batch", str(jobs_file(tmp_path, ONE))]) == 0
    (out / ".segadeform-outputs.json").unlink()
    assert main(["batch", str(jobs_file(tmp_path, TWO))]) == 0
    assert "2 jobs, 1 already done, 1 made" in capsys.readouterr().out
