"""Entry point of the ``segadeform`` command.

Every command is a thin layer over a library call.  Errors the library raises
on bad input (:class:`~segadeform.errors.SegadeformError`) and operating
system errors become one ``Error: ...`` line on stderr and exit status 1;
usage errors exit with 2 (click's convention).  No traceback is printed for
either.  An option of one value given twice is a usage error (click kept the
last).  A path option or argument is a :class:`PathParam`: a path that is not
what it must be (a folder for a file) is bad input, not a usage error.
"""

from __future__ import annotations

import os
import stat
import sys

import click

from segadeform import __version__
from segadeform.errors import SegadeformError


def _given_twice(cmd: click.Command, ctx: click.Context, args: list[str]) -> None:
    """Refuse an option that takes one value given more than once: click keeps the last and drops the others
    without a word (``run --batch 2 --batch 4`` ran at 4; ``--output a --output b`` wrote b alone).  Options declared
    ``multiple``, counts and flags (``--force --force``) are not refused.  Raises click.UsageError (exit 2), before
    anything runs.  Not while the shell completes a command line (``ctx.resilient_parsing``: a review found completion
    failing with a traceback)."""
    if ctx.resilient_parsing:
        return
    try:
        _, _, order = cmd.make_parser(ctx).parse_args(args=list(args))
    except click.UsageError:
        return  # click's own parse says what is wrong with this command line
    seen: set[str | None] = set()
    for p in order:
        if not isinstance(p, click.Option) or p.multiple or p.count or p.is_flag:
            continue
        if p.name in seen:
            raise click.UsageError(f"{p.opts[-1]} is given more than once: give it once", ctx=ctx)
        seen.add(p.name)


#: what a command stopped by Ctrl-C or SIGTERM says (train says its own: the step it resumes from); outputs are
#: committed whole or not at all
INTERRUPTED = "interrupted: nothing half-written was left; run the same command again"
#: the commands that keep each unit of work as it finishes, and go on from there when run again
_GOES_ON = {"batch": "the jobs", "dataset make": "the samples"}


def interrupted_message(command: str) -> str:
    """What ``command`` (``batch``, ``dataset make`` ...) says when stopped: :data:`INTERRUPTED`, and for a command that
    keeps its finished work, that it goes on from there (a pipeline TD's trial: `run` and `batch` spoke of dataset
    make)."""
    what = _GOES_ON.get(command)
    return INTERRUPTED + (f" (it goes on from {what} it finished)" if what else "")


class _Command(click.Command):
    def parse_args(self, ctx, args):
        _given_twice(self, ctx, args)
        ctx.meta["segadeform.command"] = " ".join(ctx.command_path.split()[1:])  # (meta: shared with the group's)
        return super().parse_args(ctx, args)


class _Group(click.Group):
    command_class = _Command
    group_class = type  # a subgroup (`dataset`, `garment` ...) is a _Group: its commands are _Commands

    def parse_args(self, ctx, args):
        _given_twice(self, ctx, args)
        return super().parse_args(ctx, args)

    def invoke(self, ctx):
        from segadeform.io.atomic import removing_made_folders

        try:
            with removing_made_folders():  # a command that fails or is stopped leaves no empty folder it made
                return super().invoke(ctx)
        except SegadeformError as e:
            raise click.ClickException(str(e)) from None
        except MemoryError:
            raise click.ClickException("out of memory (is the input much larger than expected?)") from None
        except KeyboardInterrupt:  # Ctrl-C, SIGTERM: click said "Aborted!" alone (a user's trial)
            raise click.ClickException(interrupted_message(ctx.meta.get("segadeform.command", ""))) from None
        except BrokenPipeError:
            if not _stdout_closed():  # a pipe of ours (the simulator's) broke: an error like any other
                raise click.ClickException("broken pipe") from None
            # the reader of our output stopped (`segadeform inspect X | head -1`): stop quietly, as Unix tools do
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            raise SystemExit(141) from None  # 128 + SIGPIPE
        except OSError as e:
            where = f"{e.filename}: " if getattr(e, "filename", None) else ""
            raise click.ClickException(f"{where}{e.strerror or e}") from None


class PathParam(click.Path):
    """``click.Path`` whose checks of the path itself are bad input in the readers' one wording
    (:func:`segadeform.errors.file_error`): a folder where a file is expected (``run --garment "some dir"``), a file
    where a folder is, or a path that must exist and does not is one line naming the path, exit 1 -- click said it in
    three lines of usage with exit 2, as for a command line it cannot read (an unknown option, which stays so)."""

    def __init__(self, *args, package: bool = False, **kw):
        super().__init__(*args, **kw)
        self.package = package  # a model package's folder: a checkpoint given instead is told how to make one

    def convert(self, value, param, ctx):
        from segadeform.errors import FileFormatError, file_error

        if not (self.file_okay and self.allow_dash and value in ("-", b"-")):
            path = os.fsdecode(value)
            try:
                mode = os.stat(os.path.realpath(path) if self.resolve_path else path).st_mode
            except OSError as e:
                if self.exists:
                    raise file_error(e, path) from None
            else:
                if not self.dir_okay and stat.S_ISDIR(mode):
                    raise FileFormatError("is a directory, not a file", path=path)
                if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):  # /dev/zero was read until the kernel killed the
                    # process, with no word (a fuzzer's trial); a pipe (<(...)) stays a file to read
                    what = "a file" if self.file_okay else "a folder"
                    raise FileFormatError(f"is a device, not {what}", path=path, expected=what)
                if not self.file_okay and stat.S_ISREG(mode):
                    if self.package and path.endswith(".pt"):  # a checkpoint for --model: what makes a package
                        raise FileFormatError(
                            "is a training checkpoint, not a model package",
                            path=path,
                            expected=f"a package folder: segadeform export {path} -o PACKAGE",
                        )
                    if path.endswith(".sgdpack"):  # (a user's trial: `dataset regate ... -o PACK`)
                        raise FileFormatError(
                            "is a dataset pack, which is only ever read",
                            path=path,
                            expected="a dataset folder (what dataset make writes)",
                            got="a pack",
                        )
                    raise FileFormatError("is a file, not a directory", path=path, expected="a folder")
        return super().convert(value, param, ctx)


def usable_threads(asked: int) -> tuple[int, str]:
    """``(threads, note)``: ``asked`` (a ``--threads``), at most the CPUs this process may run on (its CPU affinity;
    a container's CPU quota is not read), and the line that says so when it was lowered (``""`` otherwise).  More
    threads than CPUs only contend: 1000 took about 6 s a frame (a user's trial); Node and C++ lower it alike."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # no affinity on this platform
        cpus = os.cpu_count() or 1
    cpus = max(1, cpus)
    if asked <= cpus:
        return asked, ""
    return cpus, f"threads: {cpus}, not {asked} (the CPUs this process may use)"


def _stdout_closed() -> bool:
    """Whether nothing reads standard output any more (its pipe's reader has closed it)."""
    try:
        import select

        poll = select.poll()
        poll.register(sys.stdout.fileno(), select.POLLERR)
        return any(ev & select.POLLERR for _, ev in poll.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll (Windows), or stdout is not a file
        return False


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="segadeform")
def cli() -> None:
    """SEGA garment deformation: precompute, export and run."""


def bvh_units_option(ctx, param, value):
    """A ``--units`` option's callback (BVH units: :func:`segadeform.motion.bvh.bvh_units`): a bad value is a usage
    error naming it (exit 2; it was "scale must be positive", exit 1, naming neither: a fuzzer's trial)."""
    from segadeform.motion.bvh import bvh_units

    return None if value is None else option_value(bvh_units, value, option="--units")


def _register() -> None:
    # the commands attach themselves to `cli`; body_export, garment_export and motion_export make the runtimes'
    # inputs (docs/package.md)
    from . import (  # noqa: F401
        batch,
        body,
        body_export,
        bundle_cmd,
        cache_cmd,
        dataset,
        export,
        garment,
        garment_export,
        garment_unfit,
        info_cmd,
        inspect_cmd,
        motion,
        motion_convert,
        motion_export,
        precompute,
        preview,
        run,
        simulate,
        train,
    )


_register()


def _terminated(signum, frame):
    """SIGTERM (`timeout`, `kill`, a job scheduler) stops a command as Ctrl-C does: the exception unwinds it, so the
    simulator's process is killed and its temporary folder removed, and nothing half-written is committed (the
    default action ended the process on the spot and left both behind)."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit status instead of raising SystemExit."""
    import signal
    import threading

    previous = None
    if threading.current_thread() is threading.main_thread() and hasattr(signal, "SIGTERM"):
        previous = signal.signal(signal.SIGTERM, _terminated)
    try:
        cli.main(args=argv, prog_name="segadeform", standalone_mode=True)
    except SystemExit as e:  # click exits; turn it into a return value
        code = e.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return 0


def option_value(check, value, *, option: str):
    """``check(value, ...)`` (a library check raising :class:`InputError`), its refusal a usage error (exit 2) naming
    ``option``: a bad option value is a command-line mistake, as in the C++ and Node runtimes and as click's own
    ranges (``--batch 0``) are (a technical artist's trial: ``run --output-units furlong`` and ``--fps 0`` exited 1)."""
    import inspect

    from segadeform.errors import InputError

    try:
        return check(value, option=option) if "option" in inspect.signature(check).parameters else check(value)
    except InputError as e:
        what = e.problem.removeprefix(f"{option}: ").replace(option, "value")
        detail = ", ".join(f"{k} {v}" for k, v in (("expected", e.expected), ("got", e.got)) if v is not None)
        raise click.BadParameter(what + (f" ({detail})" if detail else ""), param_hint=f"'{option}'") from None


if __name__ == "__main__":
    sys.exit(main())
