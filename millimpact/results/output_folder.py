"""Where results go: one output policy for every command that writes (docs/outputs.md).

A command claims its output folder before it computes, then writes through the claim::

    target = claim_output(args.out or default_out(name), "compare", force=args.force)   # checks, locks
    ...compute...
    with target.staged() as stage:          # a hidden .NAME.partial-* folder
        (stage / "compare.json").write_text(...)
    say(f"results in {target.shown}/" + target.replaced_note())

The policy:

- A folder millimpact wrote holds a manifest, :data:`MARKER`: the kind of output (run, compare,
  ...) and the names it wrote. A rerun of the same kind replaces those names only; every other entry
  (the user's notes, post-processing) is left alone and said. A folder of another kind, or holding
  files and no manifest, is refused unless ``force``: then the new output is written beside what is
  there, and the entries it replaces are named.
- The path is checked before computing (:func:`prepare_output`): a file, the current folder or one
  of its parents, ``''``, or a place where no folder can be made are refused in one line. A
  symbolic link is written through: its target is the output folder, the link stays.
- Two writers of one folder exclude each other: the claim holds an advisory lock
  (``fcntl.flock``) on ``.NAME.lock`` beside the folder until the command ends. The kernel drops
  it when its holder dies, so a killed run never blocks the next; a second writer is refused in
  one line.
- The hidden ``.NAME.partial-*`` / ``.NAME.old-*`` folders a killed run leaves are removed, and
  said, by the next claim of NAME (it holds the lock, so no live writer owns them).
- A failed write (full disk, quota, I/O error) is an :class:`~millimpact.errors.OutputError`: one
  line, exit status 1; the staging folder is removed, so nothing half-written remains.
"""

from __future__ import annotations

import atexit
import errno
import glob
import json
import os
import secrets
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError, OutputError
from ..interrupts import raise_if_interrupted

#: the manifest that marks a folder as a millimpact output: {"kind", "millimpact_version", "files",
#: "beside"}: the kind last written and its names, and the names of each other kind written there
#: earlier (an output added with --force beside another: each command still owns its own entries)
MARKER = ".millimpact-output"
#: the hidden entries beside an output folder NAME that millimpact makes (stage, swap, probe, lock)
HIDDEN = (".partial-", ".old-", ".probe-")
#: errno values of a failed write that no retry fixes: said in one line, exit status 1
WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EPERM}
#: the --out and --force help of every command that writes (``OUT_HELP.format(default=...)``)
OUT_HELP = (
    "output folder (default {default}); a rerun replaces what millimpact wrote there and keeps "
    "your other files (docs/outputs.md)"
)
FORCE_HELP = (
    "write into --out even if it holds files millimpact did not write, or another kind of output "
    "(same-named entries are replaced, and named)"
)
#: the folder being written now (its interruption note is the CLI's one line on Ctrl-C)
_CURRENT: list[OutputFolder] = []
#: lock files held by this process: path -> file descriptor (kept until exit or the output is done)
_LOCKS: dict[Path, int] = {}


# --- the manifest -----------------------------------------------------------------------------------
def read_manifest(folder: Path) -> dict | None:
    """The manifest of a millimpact output, ``files`` None for one written before manifests
    (a marker without names, or an older ``summary.json`` / ``compare.json`` / ``contact_table.json``
    / ``study.json``); None for any other folder."""
    folder = Path(folder)
    try:
        data = json.loads((folder / MARKER).read_text())
        beside = data.get("beside") or {}
        return {
            "kind": data.get("kind", "run"),
            "files": data.get("files"),
            "beside": {str(k): list(v) for k, v in beside.items()} if isinstance(beside, dict) else {},
        }
    except (OSError, ValueError, AttributeError):
        pass
    version = "millimpact_version"
    for name, kind, key in (
        ("summary.json", "run", version),
        ("compare.json", "compare", version),
        ("contact_table.json", "table", version),
        ("study.json", "study", "cases"),
    ):
        try:
            if key in json.loads((folder / name).read_text()):
                return {"kind": kind, "files": None, "beside": {}}
        except (OSError, ValueError, TypeError):
            continue
    return None


def kinds_beside(manifest: dict | None, kind: str) -> dict:
    """The other kinds' names a folder with ``manifest`` holds, when ``kind`` is written into it:
    the earlier main kind's (unless it is ``kind``) and those already beside it (kind -> names)."""
    if manifest is None:
        return {}
    others = {k: set(v) for k, v in manifest.get("beside", {}).items() if k != kind}
    if manifest["kind"] != kind and manifest["files"]:
        others[manifest["kind"]] = set(manifest["files"])
    return others


def owned_names(manifest: dict | None, kind: str) -> set | None:
    """The names ``kind`` wrote in a folder with ``manifest`` (None: an output of that kind written
    before manifests named its files; empty set: none of that kind)."""
    if manifest is None:
        return set()
    if manifest["kind"] == kind:
        return None if manifest["files"] is None else set(manifest["files"])
    return set(manifest.get("beside", {}).get(kind, []))


def is_millimpact_output(folder: Path) -> bool:
    """True if ``folder`` is an output millimpact wrote (manifest, or an older output's summary)."""
    return read_manifest(folder) is not None


def write_marker(folder: Path, kind: str, files: Iterable[str] | None = None, beside: dict | None = None) -> None:
    """Write the manifest of ``folder`` (atomically): ``kind`` and the names millimpact wrote there
    (None: not known; a rerun then replaces only the names it writes again); ``beside``: other
    kinds' names in the same folder (kind -> names)."""
    from .. import __version__

    folder = Path(folder)
    names = None if files is None else sorted(set(files) - {MARKER})
    data: dict[str, Any] = {"kind": kind, "millimpact_version": __version__, "files": names}
    others = {k: sorted(set(v) - {MARKER}) for k, v in (beside or {}).items() if k != kind and v}
    if others:
        data["beside"] = others
    tmp = folder / f"{MARKER}.tmp"
    tmp.write_text(json.dumps(data) + "\n")
    os.replace(tmp, folder / MARKER)


def apply_umask(path: Path) -> None:
    """Give a folder made by :func:`tempfile.mkdtemp` (mode 0700) the mode the user's umask asks for."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o777 & ~mask)


# --- the path ---------------------------------------------------------------------------------------
def default_out(name: str, prefix: str = "", suffix: str = "") -> Path:
    """``out/<prefix><name><suffix>`` with ``name`` (a scene's or study's, free text) kept inside ``out/``:
    path separators and ``.``/``..`` parts dropped (``../../etc`` -> ``out/etc``)."""
    parts = [p for p in str(name).replace("\\", "/").split("/") if p not in ("", ".", "..")]
    return Path("out") / (prefix + ("-".join(parts) or "output") + suffix)


def prepare_output(out: Path | str, option: str = "--out", force: bool = False) -> Path:
    """Check that ``out`` can receive an output, before any computing; returns it absolute.

    Refused with an :class:`InputError` (one line naming ``option`` and the path): ``''``, an
    existing file; the current folder or one of its parents; a non-empty folder that is not a
    millimpact output (unless ``force``); a place where no folder can be made.
    """
    raw = str(out)
    if not raw.strip():
        raise InputError(f"{option} {raw!r}: is empty; give a folder (e.g. out/NAME)")
    out = Path(os.path.abspath(os.path.expanduser(raw)))
    if out.is_symlink():
        # the user's link: written through into its target, under the target's rules (the link
        # itself is never renamed, replaced or removed)
        out = Path(os.path.realpath(out))
    cwd = Path.cwd().resolve()
    if out == cwd or out in cwd.parents or out == Path(out.anchor) or out.resolve() == cwd:
        raise InputError(
            f"{option} {raw}: is the current folder or one of its parents; give a folder of its own (e.g. out/NAME)"
        )
    if out.exists() and not out.is_dir():
        raise InputError(f"{option} {raw}: is a file; give a folder")
    if out.is_dir() and any(out.iterdir()) and not is_millimpact_output(out) and not force:
        raise InputError(
            f"{option} {raw}: holds files millimpact did not write; give a new folder "
            "or add --force to write beside them"
        )
    parent = out.parent
    for p in [parent, *parent.parents]:
        if p.exists():
            if not p.is_dir():
                raise InputError(f"{option} {raw}: {p} is a file, so no folder can be made under it")
            break
    try:  # a place where a folder can be made: make the parents and a probe folder there now
        parent.mkdir(parents=True, exist_ok=True)
        probe = Path(tempfile.mkdtemp(prefix=f".{out.name}.probe-", dir=parent))
        shutil.rmtree(probe, ignore_errors=True)
    except OSError as exc:
        raise InputError(f"{option} {raw}: no folder can be made there ({exc.strerror or exc})") from None
    return out


# --- the claim --------------------------------------------------------------------------------------
@dataclass
class OutputFolder:
    """A claimed output folder (:func:`claim_output`): checked, locked, and written through
    :meth:`staged` (and :meth:`open` for a cache that outlives interruptions)."""

    path: Path  #: absolute
    shown: str  #: as the user gave it
    kind: str
    force: bool
    option: str
    comm: Any = None  #: the MPI communicator (None: serial)
    existed: bool = False  #: held entries when claimed
    said: list[str] = field(default_factory=list)  #: what publishing replaced or kept
    note: str | Callable[[], str] = ""  #: what an interruption leaves (the CLI's one line)

    @property
    def rank0(self) -> bool:
        return self.comm is None or self.comm.rank == 0

    def open(self, keep: Iterable[str], note: str | Callable[[], str] = "") -> Path:
        """Make the folder now, for entries written as the command goes (a study's case folders, a
        table's ``cases/``): recorded in the manifest at once, so an interrupted command's folder is
        still its own, and kept by :meth:`staged`. ``note``: what an interruption leaves."""
        if self.rank0:
            self.path.mkdir(parents=True, exist_ok=True)
            old = read_manifest(self.path)
            owned = owned_names(old, self.kind) or set()
            write_marker(self.path, self.kind, owned | set(keep), kinds_beside(old, self.kind))
        self.note = note or self.note
        return self.path

    @contextmanager
    def staged(self, keep: Iterable[str] = (), collective: bool = True) -> Iterator[Path]:
        """Write the output's files into a hidden staging folder beside the output and publish them
        when the block ends without an exception (:func:`publish`): the earlier output of this kind
        is replaced except ``keep`` (a cache from :meth:`open`), the user's entries stay. Collective
        when the claim has a communicator, unless not ``collective`` (rank 0 alone writes). A failed
        write is one line (``OutputError``) saying what is kept (:attr:`note`). On an exception
        the lock is dropped but the claim stays current: the CLI's line on an interruption says what
        the folder keeps (its finished cases), not that nothing was written."""
        unwritten = self.note if callable(self.note) else None
        try:
            with staged_output(
                self.path,
                self.comm if collective else None,
                self.kind,
                force=self.force,
                keep=keep,
                said=self.said,
                what=f"{self.option} {self.shown}",
                unwritten=unwritten,
            ) as stage:
                yield stage
        except BaseException:
            _unlock(self.path)
            raise
        self.release()

    def replaced_note(self) -> str:
        """`` (replaced ...; kept ...)`` for the command's "results in" line, or ''."""
        return f" ({'; '.join(self.said)})" if self.said else ""

    def release(self) -> None:
        """Drop the lock (also dropped at exit, or by the kernel when the process dies)."""
        if self in _CURRENT:
            _CURRENT.remove(self)
        _unlock(self.path)


def claim_output(out: Path | str, kind: str, force: bool = False, option: str = "--out", comm=None) -> OutputFolder:
    """Check ``out`` (:func:`prepare_output`), take its lock, remove what killed runs left there,
    and refuse a folder of another kind unless ``force``; before any computing. Collective when
    ``comm`` is given (default: MPI_COMM_WORLD under mpirun): rank 0 checks and locks."""
    from ..console import say

    comm = comm if comm is not None else _world()
    raw = str(out)
    result, error = None, None
    if comm is None or comm.rank == 0:
        try:
            path = prepare_output(out, option, force)
            _lock(path, f"{option} {raw}")
            disk = os.statvfs(path.parent)
            if disk.f_bavail * disk.f_frsize == 0:
                _unlock(path)
                raise OutputError(f"{option} {raw}: the disk is full (0 bytes free there); free some space first")
            leftovers = remove_leftovers(path)
            old = read_manifest(path) if path.is_dir() else None
            if old is not None and old["kind"] != kind and kind not in old["beside"] and not force:
                _unlock(path)
                raise InputError(
                    f"{option} {raw}: holds a millimpact {old['kind']} output, not {_a(kind)}; give "
                    f"a new folder, or add --force to write the {kind} beside it"
                )
            existed = path.is_dir() and any(p.name != MARKER for p in path.iterdir())
            result = (str(path), existed, leftovers)
        except (InputError, OutputError) as exc:
            error = (type(exc).__name__, str(exc))
    if comm is not None and comm.size > 1:
        result, error = comm.bcast((result, error), root=0)
    if error is not None:
        raise (OutputError if error[0] == "OutputError" else InputError)(error[1])
    assert result is not None  # claimed on rank 0 and broadcast, or an error raised above
    path_text, existed, leftovers = result
    for name in leftovers:
        say(f"note: removed {name}, left by an interrupted millimpact beside {raw}")
    target = OutputFolder(Path(path_text), raw, kind, force, option, comm, existed)
    target.note = f"nothing written to {raw}/" + (" (its earlier content is kept)" if existed else "")
    _CURRENT[:] = [target]
    return target


def interrupt_note() -> str:
    """What an interruption leaves, for the CLI's one line."""
    if not _CURRENT:
        return "no output was written"
    note = _CURRENT[0].note
    return note() if callable(note) else note


def remove_leftovers(path: Path) -> list[str]:
    """Remove the ``.NAME.partial-*`` / ``.NAME.old-*`` / ``.NAME.probe-*`` beside ``path`` and the
    staging folders inside it that a killed run left; returns their names. Call with the lock held."""
    found = [p for p in path.parent.glob(f".{glob.escape(path.name)}.*") if any(h in p.name for h in HIDDEN)]
    if path.is_dir():
        found += [p for p in path.glob(".*.partial-*")]
    for p in found:
        shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
    return sorted(p.name for p in found)


def _lock_path(path: Path) -> Path:
    return path.parent / f".{path.name}.lock"


def _lock(path: Path, what: str) -> None:
    """Take the lock of ``path`` or refuse in one line (held until :meth:`OutputFolder.release`)."""
    import fcntl

    lock = _lock_path(path)
    if lock in _LOCKS:  # this process holds it already (an API caller claiming again)
        return
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise InputError(
                f"{what}: another millimpact (process {holder}) is writing there; wait for it or give another folder"
            ) from None
        try:  # the file may have been replaced since it was opened (a holder unlinked it at the end)
            if os.fstat(fd).st_ino == os.stat(lock).st_ino:
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:  # the holder's process id, for the refusal's line (nothing depends on it)
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
    except OSError:
        pass
    if not _LOCKS:
        atexit.register(_unlock_all)
    _LOCKS[lock] = fd


def _unlock(path: Path) -> None:
    lock = _lock_path(path)
    fd = _LOCKS.pop(lock, None)
    if fd is not None:
        lock.unlink(missing_ok=True)  # while held: a waiter that opened it sees the inode change
        os.close(fd)


def _unlock_all() -> None:
    for lock in list(_LOCKS):
        _unlock(lock.parent / lock.name[1 : -len(".lock")])


def release_locks() -> None:
    """Drop every output lock this process holds now (a process about to be killed: the kernel
    would drop the locks, but their files would stay beside the folders)."""
    _unlock_all()


def _world():
    """MPI_COMM_WORLD under mpirun (more than one rank), else None (no MPI import)."""
    if int(os.environ.get("OMPI_COMM_WORLD_SIZE", os.environ.get("PMI_SIZE", "1"))) > 1:
        from mpi4py import MPI

        return MPI.COMM_WORLD
    return None


# --- staging and publishing ---------------------------------------------------------------------------
@contextmanager
def staged_output(
    out: Path,
    comm=None,
    kind: str = "run",
    force: bool = False,
    keep: Iterable[str] = (),
    said: list[str] | None = None,
    what: str = "",
    unwritten: Callable[[], str] | None = None,
) -> Iterator[Path]:
    """Write an output's files into a hidden staging folder ``.NAME.partial-*`` and :func:`publish`
    it to ``out`` only on success. Collective when ``comm`` is given: rank 0 makes the folder and
    every rank gets its path (collective writers such as XDMF); only rank 0 publishes. An exception
    (an interruption too) leaves ``out`` untouched and removes the staging folder; a failed write
    (full disk ...) becomes an ``OutputError`` naming ``what`` (default the path) and what is left
    (``unwritten()``, default: nothing was written)."""
    rank = comm.rank if comm is not None else 0
    out = Path(os.path.abspath(out))
    what = what or str(out)
    stage = None
    # the staging folder is named before it is made, inside the block that removes it: a Ctrl-C
    # just after its mkdir (inside tempfile.mkdtemp, or before this block began) left it behind
    # empty, in 2 of ~35 interrupts sent as mill's first line came out
    try:
        if rank == 0:
            try:
                out.parent.mkdir(parents=True, exist_ok=True)
                while stage is None:  # as tempfile.mkdtemp (mode 0700, a fresh random name)
                    stage = out.parent / f".{out.name}.partial-{secrets.token_hex(4)}"
                    try:
                        os.mkdir(stage, 0o700)
                    except FileExistsError:  # another's: not ours to remove
                        stage = None
                apply_umask(stage)
            except OSError as exc:  # a write failure in one line; any other OSError as it is
                raise (_write_error(exc, what, unwritten) or exc) from None
        if comm is not None:
            stage = Path(comm.bcast(str(stage) if stage else None, root=0))
        assert stage is not None  # made on rank 0 (or the error raised there) and broadcast
        error: BaseException | None = None
        try:
            yield stage
            raise_if_interrupted()  # a Ctrl-C / SIGTERM whose exception a library swallowed
        except Exception as exc:  # agreed on by all ranks below: none waits for one that failed
            error = exc
        if comm is not None and comm.size > 1 and comm.allreduce(error is not None) and error is None:
            error = OutputError(f"{what}: another rank failed writing; nothing was written")
            error.said_by_rank0 = True  # the CLI leaves the line to the rank that failed
        if error is not None:
            raise error
        if rank == 0:
            done = publish(stage, out, kind, force, keep)
            if said is not None:
                said[:] = done
    except BaseException as exc:
        if rank == 0 and stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        error = _write_error(exc, what, unwritten) if isinstance(exc, (OSError, RuntimeError)) else None
        if error is not None:
            raise error from None
        raise


def publish(stage: Path, out: Path, kind: str, force: bool = False, keep: Iterable[str] = ()) -> list[str]:
    """Move the complete ``stage`` to ``out``; returns what was said to be replaced or kept.

    A new folder, or one holding only the earlier output of this kind: one rename (the old folder
    swapped out whole). Otherwise entry by entry, the manifest first naming old and new (a publish
    killed half-way leaves a folder the next run still knows as its own): the earlier output's
    entries are replaced (``keep``: left), the others stay; an entry of the same name as a new one
    is replaced under ``force`` and named, else kept renamed ``NAME.yours``."""
    new = sorted(p.name for p in stage.iterdir())
    old = read_manifest(out) if out.is_dir() else None
    present = {p.name for p in out.iterdir()} - {MARKER} if out.is_dir() else set()
    keep = set(keep) & present
    owned = owned_names(old, kind)
    if owned is None:  # written before manifests: what this output writes again is its
        owned = present & set(new)
    owned = (owned & present) - keep
    # the other kinds' entries (an output added beside another with --force): still theirs
    others = {k: (v & present) - owned - keep for k, v in kinds_beside(old, kind).items()}
    theirs = set().union(*others.values()) if others else set()
    foreign = present - owned - keep - theirs
    write_marker(stage, kind, new)
    said = [f"replaced the earlier {kind}'s {len(owned)} {_entries(len(owned))}"] if owned else []
    if not present - owned:  # nothing else there: swap the whole folder
        trash = out.parent / f".{out.name}.old-{os.getpid()}"
        if out.exists():
            out.rename(trash)
        stage.rename(out)
        shutil.rmtree(trash, ignore_errors=True)
        return said
    clash = (foreign | theirs) & set(new)
    others = {k: v - clash for k, v in others.items()}
    write_marker(out, kind, (owned | keep | set(new)) - foreign - theirs, others)
    trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
    for name in sorted(owned | clash):
        if name in clash and not force:
            os.rename(out / name, out / _free_name(out, f"{name}.yours"))
        else:
            os.rename(out / name, trash / name)
    for name in new:
        os.rename(stage / name, out / name)
    write_marker(out, kind, set(new) | keep, others)
    shutil.rmtree(trash, ignore_errors=True)
    shutil.rmtree(stage, ignore_errors=True)
    if clash:
        said.append(f"{'replaced with --force' if force else 'kept yours as NAME.yours'}: {', '.join(sorted(clash))}")
    for k, v in sorted(others.items()):
        if v:
            said.append(f"kept the {k}'s {len(v)} {_entries(len(v))}")
    if foreign - clash:
        rest = sorted(foreign - clash)
        said.append(
            f"kept {len(rest)} {_entries(len(rest))} millimpact did not write: {', '.join(rest[:5])}"
            + (" ..." if len(rest) > 5 else "")
        )
    return said


def _a(kind: str) -> str:
    """``kind`` with its article: "a table", "an export"."""
    return f"{'an' if kind[:1] in 'aeiou' else 'a'} {kind}"


def _entries(n: int) -> str:
    return "entry" if n == 1 else "entries"


def _free_name(folder: Path, name: str) -> str:
    n, candidate = 1, name
    while (folder / candidate).exists():
        n += 1
        candidate = f"{name}-{n}"
    return candidate


# --- failed writes ------------------------------------------------------------------------------------
def _write_error(exc: BaseException, what: str, unwritten: Callable[[], str] | None = None) -> OutputError | None:
    """The one-line :class:`OutputError` of a failed write (an OSError with a write errno, or the
    RuntimeError HDF5 raises for one), else None (not a write failure: raised as it is)."""
    if isinstance(exc, OutputError):
        return exc
    code = getattr(exc, "errno", None)
    if code is None:
        text = str(exc)
        code = next((c for c in WRITE_ERRNOS if f"errno = {c}," in text or os.strerror(c) in text), None)
    if code not in WRITE_ERRNOS:
        return None
    name = Path(getattr(exc, "filename", None) or "").name
    left = unwritten() if unwritten is not None else "nothing was written (what was there before is unchanged)"
    return OutputError(f"{what}: {os.strerror(code)}{f' writing {name}' if name else ''}; {left}")


@contextmanager
def hdf5_file(path: Path) -> Iterator[Any]:
    """An ``h5py.File`` built in memory and written to ``path`` in one write when the block ends.

    HDF5 writing straight to a full disk fails inside its own close, leaves the file open in the
    library and crashes at interpreter exit (SIGSEGV; PETSc's handler then calls MPI_Abort, exit
    59: measured on a 1 MB tmpfs, tests/results/test_output_policy.py). Built in memory, a full
    disk is an ordinary OSError of the final write."""
    import h5py

    h5 = h5py.File(f"{path}.inmemory", "w", driver="core", backing_store=False)
    try:
        yield h5
        h5.flush()
        image = h5.id.get_file_image()
    finally:
        h5.close()
    with open(path, "wb") as fh:
        fh.write(image)
