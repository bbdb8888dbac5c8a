"""Each command lives in the module its group names (cli/), and moving one changes nothing it prints."""

from __future__ import annotations

import click
from click.testing import CliRunner

from segadeform.cli.main import cli

from ..conftest import SAMPLES

#: top-level commands that live beside the command whose output they take
SIBLINGS = {"quantize": "export", "repack": "export", "eval": "train", "ensemble": "train"}


def _commands(group, prefix=()):
    for name, cmd in group.commands.items():
        yield (*prefix, name), cmd
        if isinstance(cmd, click.Group):
            yield from _commands(cmd, (*prefix, name))


def test_commands_live_in_the_modules_their_names_say():
    """``segadeform X`` lives in ``cli/X.py`` (``X_cmd.py`` where X is a standard module's name), a subcommand
    ``G S`` in its group's module or ``cli/G_S.py``, and a module holds one command or one group: so a command is
    found from its name alone."""
    owners = {}
    for path, cmd in _commands(cli):
        module = cmd.callback.__module__
        assert module.startswith("segadeform.cli."), (path, module)
        stem = module.rsplit(".", 1)[1].removesuffix("_cmd")
        top = SIBLINGS.get(path[0], path[0]).replace("-", "_")
        words = top.split("_")
        ok = stem == top or (len(path) > 1 and stem == f"{path[0]}_{path[1]}") or stem == "_".join(words[::-1])
        assert ok, f"`segadeform {' '.join(path)}` lives in {module}"
        owners.setdefault(module, set()).add(SIBLINGS.get(path[0], path[0]))
    assert {m: o for m, o in owners.items() if len(o) > 1} == {}
    assert len(owners) >= 15


def test_info_prints_the_package():
    r = CliRunner().invoke(cli, ["info", str(SAMPLES / "models" / "default")])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0].startswith(f"{SAMPLES / 'models' / 'default'}: segadeform-model-package schema ")
    assert lines[1].startswith("  units m, up +y, 24 joints") and lines[2].startswith("  config: {")
    assert any(ln.startswith("  ops (") for ln in lines)


def test_every_command_refuses_an_option_of_one_value_given_twice(tmp_path, monkeypatch):
    """Click kept the last of ``run --batch 2 --batch 4`` and dropped the first without a word (a user's trial: the
    node runtime refused it, the Python CLI ran).  Every command and group refuses each of its single-value options
    given twice, before it runs: usage error, exit 2, the option named.  Options of several values (``multiple``),
    counts and flags stay as they are."""
    cases = [
        (path, p)
        for path, cmd in [((), cli), *_commands(cli)]
        for p in cmd.params
        if isinstance(p, click.Option) and not (p.is_flag or p.count or p.is_eager)
    ]
    runner = CliRunner()
    checked = 0
    monkeypatch.chdir(tmp_path)  # a command that did run would write here only
    for path, p in cases:
        value = ["1"] * max(p.nargs, 1)
        r = runner.invoke(cli, [*path, p.opts[0], *value, p.opts[0], *value], catch_exceptions=False)
        if p.multiple:
            assert "given more than once" not in r.output, (path, p.name, r.output)
            continue
        assert r.exit_code == 2, (path, p.name, r.exit_code, r.output)
        assert f"{p.opts[-1]} is given more than once" in r.output, (path, p.name, r.output)
        checked += 1
    # a flag given twice is not refused
    r = runner.invoke(cli, ["garment", "kinds", "--help", "--help"])
    assert r.exit_code == 0 and "Usage:" in r.output, r.output
    # nor does the shell's completion fail on a line that gives one twice (a review: a traceback, exit 1)
    env = {"COMP_WORDS": "segadeform run --batch 2 --batch 3 --b", "COMP_CWORD": "6"}
    r = runner.invoke(cli, [], prog_name="segadeform", env={**env, "_SEGADEFORM_COMPLETE": "bash_complete"})
    assert r.exit_code == 0 and "plain,--body" in r.output and "given more than once" not in r.output, r.output
    assert checked > 100


def test_a_command_interrupted_says_so_in_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    """Ctrl-C or SIGTERM in `dataset make` or `export` printed click's "Aborted!" alone (a user's trial); every
    command now says what is left and what to do (train says its own: the step it resumes from)."""
    import segadeform.motion
    from segadeform.cli.main import INTERRUPTED, main

    def stop(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(segadeform.motion, "make_motion", stop)
    out = tmp_path / "walk.npz"
    assert main(["motion", "make", "walk", "--seconds", "0.5", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err == f"Error: {INTERRUPTED}\n" and "Aborted" not in err and not out.exists()
    assert "dataset make" not in err  # (a pipeline TD's trial: every command spoke of it)
    monkeypatch.setattr("segadeform.runtime.batch.run_batch", stop)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f'[[garments]]\nmesh = "{SAMPLES / "garments" / "skirt.obj"}"\n[[motions]]\nkind = "walk"\n')
    assert main(["batch", str(jobs), "-o", str(tmp_path / "b")]) == 1
    assert capsys.readouterr().err == f"Error: {INTERRUPTED} (it goes on from the jobs it finished)\n"


def test_a_run_interrupted_while_writing_leaves_no_empty_folder(tmp_path, monkeypatch, capsys):
    """`run -o new/deeper/out.pc2` stopped after its writer had begun left `new/deeper/` behind, empty (a session's
    trial with SIGTERM); the folders a stopped command made for its outputs go with its temporaries."""
    import segadeform.io.pc2
    from segadeform.cli.main import INTERRUPTED, main

    def stop(self, frames):
        assert self._tmp.parent.is_dir()  # the writer made the folders and its temporary: then the stop
        raise KeyboardInterrupt

    monkeypatch.setattr(segadeform.io.pc2.PC2Writer, "_append", stop)
    out = tmp_path / "new" / "deeper" / "out.pc2"
    argv = [
        "run",
        "--garment",
        str(SAMPLES / "garments" / "skirt.obj"),
        "--motion",
        str(SAMPLES / "motions" / "walk.npz"),
    ]
    assert main([*argv, "--frames", "0:4", "-o", str(out)]) == 1
    assert capsys.readouterr().err.endswith(f"Error: {INTERRUPTED}\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
