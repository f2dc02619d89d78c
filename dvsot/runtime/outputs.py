"""Outputs: paths checked before any work (exit 2), written as temps and renamed into place, a run's all at once.

* `output_file` / `output_dir`: the checks every command runs before it starts (a file output is missing or a regular
  file: never a device, FIFO, socket or directory, nor a path ending in a slash; a probe
  file created and removed in the target directory), plus the clean-up of temps that dead local
  processes left there (dvsot.runtime.staging).
* `replacing(path)`: a temp to write; renamed onto `path` when the block succeeds, removed otherwise.
* `run_outputs()`: every output staged inside the block (by `replacing`, `stage`, the dataset writer)
  is renamed into place together when the block ends, or none is. The renames run with SIGINT/SIGTERM
  deferred, after a journal naming them all is on disk, so a SIGKILL midway is completed by the next
  run; a manifest (the journal, complete) written last names the run and each file's SHA-256.
* `readable(path)`: where a file the open run has staged but not committed is read meanwhile (a run that
  reads its own outputs back, as a sweep tracks the files it simulated).
* `run_outputs(manifest, whole=True)`: the manifest's directory holds this run's files only: what the
  previous run's manifest names and this run does not write is removed in the same commit;
  `run_dir(root, flag, writes)` checks before any work that the directory holds no one else's files and
  that every path the run writes under it can be made (no file where a directory goes), and removes
  the temps dead processes left anywhere in it; `run_dir` inside an open whole run also knows that run's
  previous files (a run nested in another's tree, as a benchmark inside an experiment's output).
  `owned_run(root, flag, writes)`: both, and a failed run's new directories removed with its staged files.
* A symlink given as an output is written through: the temp goes beside the link's target and the
  rename replaces the target; the link stays.
* Writing errors from the operating system (a full disk, a file system gone read-only) become one
  `RunError` line naming the output: exit status 1, nothing replaced, no temp left.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import hashlib
import os
import re
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from dvsot.core.errors import RunError, UserError
from dvsot.runtime import interrupts, staging

MANIFEST_FORMAT = "dvsot-run"
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS}
_DISK_WORDS = ("No space left on device", "Disk quota exceeded", "Read-only file system", "errno = 28",
               "File too large")
# numpy's tofile (np.save) reports a short fwrite without an errno; on a regular file only a full disk, a quota
# or a size limit makes one
_SHORT_WRITE = re.compile(r"\b\d+ requested and \d+ written\b")


def target(path: str | os.PathLike) -> Path:
    """Where writing `path` lands: the path itself, or the end of its chain of symlinks."""
    p = Path(path)
    if not p.is_symlink():
        return p
    try:
        return Path(os.path.realpath(p, strict=True))
    except FileNotFoundError:  # a dangling link: writing creates the file it names
        return Path(os.path.realpath(p))
    except OSError as exc:  # a loop: it names no file, and writing would replace a link
        raise UserError(f"{p}: a symbolic link that leads to no file ({exc.strerror or exc}); "
                        f"remove it or name another output") from None


def check_writable(directory: str | os.PathLike, what: str) -> None:
    """Create and remove a probe file in `directory`; UserError naming `what` if that fails."""
    d = Path(directory)
    probe = staging.temp_name(d / "probe", suffix="")
    try:
        os.close(os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        os.unlink(probe)
    except OSError as exc:
        raise UserError(f"{what}: cannot write in {d} ({exc.strerror or exc})") from None
    finally:  # gone already, unless a signal landed between the create and the unlink (the name is this run's)
        with contextlib.suppress(OSError):
            os.unlink(probe)


def refuse_non_regular(path: str | os.PathLike, flag: str) -> None:
    """UserError unless `path` (through its symlinks) is missing or a regular file: a file output never replaces a
    device, FIFO, socket or directory; and a path ending in a slash names a directory, never a file to write."""
    text = os.fspath(path)
    if text.endswith(("/", os.sep)) or os.path.basename(text) in ("", ".", ".."):
        raise UserError(f"{text}: {flag} ends in a slash (a directory); name the file to write")
    from dvsot.core.bounds import file_kind_problem

    problem = file_kind_problem(text)
    if problem is None or problem == "no such file":  # a missing directory on the way is reported by the caller
        return
    if problem.startswith("is "):
        raise UserError(f"{text}: {flag} names {problem.removeprefix('is ')}, not a file it may replace")
    raise UserError(f"{text}: {flag}: {problem}")


def output_file(path: str | Path, flag: str, inputs: Iterable[str | Path] = ()) -> Path:
    """`path` as a file a command may (re)write: its directory exists and is writable, it is missing or a regular file
    (never a device, FIFO, socket or directory, nor a path ending in a slash), and no input."""
    refuse_non_regular(path, flag)
    p = Path(path)
    t = target(p)
    if not t.parent.is_dir():
        where = f" (a symlink to {t})" if t != p else ""
        raise UserError(f"{p}: {flag}{where}: directory {t.parent} does not exist")
    if p.exists():
        for i in inputs:
            if Path(i).exists() and os.path.samefile(p, i):
                raise UserError(f"{p}: {flag} would overwrite an input file")
    check_writable(t.parent, f"{p}: {flag}")
    staging.clean_stale(t.parent)
    return p


def output_dir(path: str | Path, flag: str) -> Path:
    """`path` as a directory a command may write into (made later, when there is output): not a file, writable."""
    p = Path(path)
    if p.is_symlink() and not p.exists():  # a loop or a dangling link: no directory can be made there
        raise UserError(f"{p}: {flag} is a symbolic link that leads to no directory; remove it or name another")
    if p.exists() and not p.is_dir():
        raise UserError(f"{p}: {flag} names a file, not a directory")
    for parent in [p, *p.parents]:
        if parent.exists():
            if not parent.is_dir():
                raise UserError(f"{p}: {flag}: {parent} is a file, not a directory")
            check_writable(parent, f"{p}: {flag}")
            if parent == p:
                staging.clean_stale(p)
            break
    return p


def previous_files(manifest: Path) -> set[str]:
    """The files (relative to its directory) an earlier run's manifest names; empty if there is none."""
    import json

    from dvsot.runtime.inputs import read_text

    try:
        text = read_text(manifest, "an earlier run's manifest", missing_ok=True)  # a FIFO there: refused, no wait
        data = json.loads(text) if text is not None else None
    except (OSError, ValueError) as exc:
        if isinstance(exc, UserError):
            raise
        return set()
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT or not isinstance(data.get("files"), dict):
        return set()
    return {str(k) for k in data["files"]}


def run_dir(root: str | Path, flag: str, writes: Iterable[str | Path], manifest: str = "run.json",
            depth: int = 4) -> Path:
    """Check the directory a run owns whole (see run_outputs(whole=True)) before any work.

    Every path in `writes` (relative to root, or under it) can be written: each directory on its way is a
    directory or missing, the path itself no directory. Temps of dead processes anywhere in the tree (down to
    `depth` levels) are removed (completing their commits); files that neither the previous run's manifest
    names nor this run writes are refused (another run's, or the user's).
    """
    root = output_dir(root, flag)
    rel = {Path(os.path.relpath(Path(root) / w, root)) for w in writes}
    collision = tree_collision(rel)
    if collision:
        raise UserError(f"{root}: {flag}: {collision}; rename one")
    for r in sorted(rel):
        if r.parts[0] == "..":
            raise ValueError(f"{r}: not under {root}")
        for k in range(1, len(r.parts) + 1):
            p = Path(root, *r.parts[:k])
            if k < len(r.parts) and (p.exists() or p.is_symlink()) and not p.is_dir():
                raise UserError(f"{p}: {flag}: a file where the directory of {Path(root, r)} goes")
            if k == len(r.parts) and p.is_dir():
                raise UserError(f"{p}: {flag}: a directory where this run writes a file")
            if k == len(r.parts):
                refuse_non_regular(p, flag)  # a FIFO, socket or device where this run writes a file
    if not root.is_dir():
        return root
    for d, dirs, _ in os.walk(root):
        if len(Path(d).relative_to(root).parts) >= depth:
            dirs[:] = []
        staging.clean_stale(d)
        if d != str(root):
            check_writable(d, f"{d}: {flag}")
    known = previous_files(root / manifest) | {str(r) for r in rel} | {manifest}
    outer = current_run()
    if outer is not None and outer.whole:  # inside a run that owns a tree around root: its previous files are known
        home = os.path.realpath(target(outer.manifest).parent)
        for name in previous_files(outer.manifest):
            r = os.path.relpath(os.path.join(home, name), os.path.realpath(root))
            if r.split(os.sep)[0] != os.pardir:
                known.add(r)
    strangers = []
    for d, dirs, files in os.walk(root):
        for name in files + [x for x in dirs if os.path.islink(os.path.join(d, x))]:
            r = os.path.relpath(os.path.join(d, name), root)
            if r not in known and not staging.is_temp(name):
                strangers.append(r)
        if len(strangers) > 3:
            break
    if strangers:
        raise UserError(f"{root}: {flag} holds files that are not an earlier run's of this command "
                        f"({', '.join(sorted(strangers)[:3])}{' ...' if len(strangers) > 3 else ''}): it holds one "
                        "run's files only; choose another directory or empty this one")
    return root


def tree_collision(files: Iterable[str | os.PathLike]) -> str | None:
    """Why a set of relative file paths cannot all be written in one tree (a file where another path needs a
    directory; two names equal up to case, which one file on a case-insensitive file system), else None."""
    paths = {Path(f) for f in files}
    dirs = {p for f in paths for p in f.parents if p != Path(".")}
    for f in sorted(paths & dirs):
        inner = next(p for p in sorted(paths) if f in p.parents)
        return f"{f} is written as a file and is also the directory of {inner}"
    seen: dict[str, Path] = {}
    for p in sorted(paths | dirs):
        other = seen.setdefault(str(p).casefold(), p)
        if other != p:
            return f"{other} and {p} differ only in case (one file on a case-insensitive file system)"
    return None


def disk_error(exc: BaseException) -> str | None:
    """The reason, if `exc` (or what caused it) is the operating system refusing a write, else None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and exc.errno in _DISK_ERRNOS:
            return os.strerror(exc.errno)
        text = str(exc)
        for words in _DISK_WORDS:
            if words in text:
                return "No space left on device" if words == "errno = 28" else words
        if isinstance(exc, OSError) and exc.errno is None and _SHORT_WRITE.search(text):
            return f"a short write: {text}; the disk is full or a size limit was reached"
        exc = exc.__cause__ or exc.__context__
    return None


@contextmanager
def writing(path: str | os.PathLike) -> Iterator[None]:
    """Turn an operating-system write failure inside the block into one RunError line naming `path`."""
    try:
        yield
    except (OSError, RuntimeError) as exc:
        reason = disk_error(exc)
        if reason is None:
            raise
        raise RunError(f"{path}: cannot write ({reason}); nothing was replaced") from None


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class RunOutputs:
    """The outputs of one run: each staged as a temp beside its target, all renamed together by `commit()`."""

    def __init__(self, manifest: str | os.PathLike | None = None, whole: bool = False) -> None:
        self.whole = whole and manifest is not None
        self.token = staging.new_token()
        self.run_id = f"{staging.host()}-{os.getpid()}-{self.token}"
        self.manifest = Path(manifest) if manifest is not None else None
        self._entries: dict[Path, dict] = {}  # final (resolved) -> {"staged", "kind", "old", "ready"}
        self._names: dict[Path, Path] = {}  # as given -> final

    def stage(self, path: str | os.PathLike, ready: bool = True) -> Path:
        """A temp path for the file `path` (same suffix), renamed onto it at commit; `ready=False` until `done()`."""
        final = target(path)
        if final in self._entries:
            return Path(self._entries[final]["staged"])
        refuse_non_regular(path, "output")  # every writer's last guard; commands check with output_file before work
        interrupts.resume()  # new work after a commit: a signal that came after it stops the run here
        staging.clean_stale(final.parent)
        tmp = staging.temp_name(final, token=self.token)
        self._entries[final] = {"staged": tmp, "kind": "file", "old": None, "ready": ready}
        self._names[Path(path)] = final
        return tmp

    def stage_dir(self, path: str | os.PathLike) -> Path:
        """A new empty directory that replaces the directory `path` (whole) at commit."""
        final = target(path)
        interrupts.resume()
        final.parent.mkdir(parents=True, exist_ok=True)
        staging.clean_stale(final.parent)
        tmp = staging.temp_name(final, token=self.token, suffix="")
        tmp.mkdir()
        old = staging.temp_name(final, "old", token=self.token, suffix="")
        self._entries[final] = {"staged": tmp, "kind": "dir", "old": old, "ready": True}
        self._names[Path(path)] = final
        return tmp

    def remove(self, path: str | os.PathLike) -> None:
        """Remove the file `path` in the commit (an earlier output that belongs with the ones replaced now)."""
        final = target(path)
        if final not in self._entries:
            refuse_non_regular(path, "output")
            self._entries[final] = {"staged": None, "kind": "gone", "old": str(final.parent), "ready": True}

    def staged(self, path: str | os.PathLike) -> Path:
        """The temp that holds `path`'s new content until the commit."""
        return Path(self._entries[target(path)]["staged"])

    def done(self, path: str | os.PathLike) -> None:
        """Mark the staged file of `path` complete (writers that stage first and finish later)."""
        self._entries[target(path)]["ready"] = True

    def drop(self, path: str | os.PathLike) -> None:
        """Forget `path`'s staged file and remove it (its writer failed)."""
        e = self._entries.pop(target(path), None)
        if e is not None:
            staging._remove(Path(e["staged"]))

    def abort(self) -> None:
        """Remove every staged temp; nothing at any target is touched."""
        for e in self._entries.values():
            if e["staged"]:
                staging._remove(Path(e["staged"]))
        self._entries.clear()

    def _manifest_body(self, journal: Path) -> dict:
        root = self.manifest.parent if self.manifest else journal.parent
        files = {}
        for final, e in self._entries.items():
            if e["kind"] == "gone":
                continue
            rel = os.path.relpath(final, root)
            staged = Path(e["staged"])
            files[rel] = ({"kind": "dir", "files": sum(1 for _ in staged.rglob("*"))} if e["kind"] == "dir" else
                          {"size": staged.stat().st_size, "sha256": _sha256(staged)})
        return {"format": MANIFEST_FORMAT, "run": self.run_id, "written_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                time.gmtime()), "files": files}

    def commit(self) -> None:
        """Rename every staged output into place (a journal first, the manifest last), or none if interrupted."""
        if not self._entries:
            return
        missing = [str(f) for f, e in self._entries.items() if not e["ready"]]
        if missing:
            raise RuntimeError(f"staged outputs never completed: {', '.join(missing)}")
        if self.whole:  # the previous run's files this run does not write go in the same commit
            root = target(self.manifest).parent
            for rel in sorted(previous_files(self.manifest)):
                final = target(root / rel)
                if final not in self._entries and final != target(self.manifest) and os.path.lexists(root / rel):
                    self._entries[final] = {"staged": None, "kind": "gone", "old": str(root), "ready": True}
        interrupts.check()  # a signal or a dead parent before the commit: nothing is replaced
        entries = [{"final": str(f), "staged": str(e["staged"]) if e["staged"] else None, "kind": e["kind"],
                    "old": str(e["old"]) if e["old"] else None} for f, e in self._entries.items()]
        if len(entries) == 1 and entries[0]["kind"] == "file" and self.manifest is None:
            with interrupts.deferred(), interrupts.committing():  # a task's run, stopped meanwhile, refuses
                interrupts.check()
                interrupts.finish()  # a command's last step is complete from here on
                os.replace(entries[0]["staged"], entries[0]["final"])  # one rename is atomic: no journal needed
                self._entries.clear()
            return
        first = Path(entries[0]["final"])
        home = self.manifest.parent if self.manifest else first.parent
        journal = staging.temp_name(self.manifest or first, "commit", token=self.token, suffix=".json")
        for e in entries:
            if e["kind"] == "file":
                _fsync(Path(e["staged"]))
        entries.sort(key=lambda e: e["kind"] == "gone")  # the new files first, then the old ones go
        body = self._manifest_body(journal)
        dirs = sorted({str(Path(e["final"]).parent) for e in entries if e["kind"] != "gone"} - {str(home)})
        pointers = [staging.temp_name(Path(d) / journal.name, "commit", token=self.token, suffix=".json")
                    for d in dirs]
        body.update(entries=entries, pointers=[str(p) for p in pointers],
                    manifest=str(self.manifest) if self.manifest else None)
        written = []
        try:
            with interrupts.deferred(), interrupts.committing():
                interrupts.check()
                interrupts.finish()
                for p in pointers:  # other directories' temps belong to this commit once the journal exists
                    staging.write_json(p, {"journal": str(journal)}, self.token)
                    written.append(p)
                staging.write_json(journal, body, self.token)  # from here on, the run is complete on disk
                written = []
                self._entries.clear()  # the journal owns the staged files now: never removed, only renamed
                try:
                    staging.apply_journal(journal)
                except ValueError as exc:  # checked before any rename: nothing replaced, the staged files gone
                    raise RunError(f"{first}: this run's outputs were not put in place ({exc})") from None
                except OSError as exc:
                    raise RunError(f"{first}: renaming this run's outputs into place failed ({exc.strerror or exc}); "
                                   f"the next dvsot run in {journal.parent} completes it from {journal.name}") from None
        finally:
            for p in written:
                p.unlink(missing_ok=True)


_current: contextvars.ContextVar[RunOutputs | None] = contextvars.ContextVar("dvsot_run_outputs", default=None)


def current_run() -> RunOutputs | None:
    """The run whose `run_outputs()` block is open, if any."""
    return _current.get()


def readable(path: str | os.PathLike) -> Path:
    """Where `path`'s content is read now: its staged temp while the open run holds it uncommitted, else the path."""
    run = _current.get()
    if run is not None:
        e = run._entries.get(target(path))
        if e is not None and e["staged"]:
            return Path(e["staged"])
    return Path(path)


@contextmanager
def run_outputs(manifest: str | os.PathLike | None = None, whole: bool = False) -> Iterator[RunOutputs]:
    """All outputs staged in the block are committed together at its end (or removed on an exception).

    `manifest`: where to write the run's manifest (JSON: run id, each file's size and SHA-256); None
    writes none (the journal still makes the commit all-or-nothing). `whole`: the manifest's directory is
    this run's alone: the files the previous manifest there names and this run does not write are removed
    by the commit (check it first with `run_dir`). Nested blocks join the outer run.
    """
    outer = _current.get()
    if outer is not None:
        yield outer
        return
    run = RunOutputs(manifest, whole)
    token = _current.set(run)
    try:
        yield run
        _current.reset(token)
        token = None
        first = next(iter(run._entries), manifest or "output")
        with writing(first):
            run.commit()
    finally:
        if token is not None:
            _current.reset(token)
        run.abort()


@contextmanager
def owned_run(root: str | Path, flag: str, writes: Iterable[str | Path],
              manifest: str = "run.json") -> Iterator[RunOutputs]:
    """One run that owns the directory `root` whole: `run_dir`'s checks first (UserError before any work), then
    `run_outputs(root / manifest, whole=True)`. A block that raises leaves root as it was: the staged files go
    and so do the directories the block made (empty once they are gone), root itself and its parents included."""
    root = Path(root)
    run_dir(root, flag, writes, manifest)
    missing = [p for p in [root, *root.parents] if not p.exists()]  # made by the run's first mkdir, if any
    before = {d for d, _, _ in os.walk(root)}
    try:
        with run_outputs(root / manifest, whole=True) as run:
            yield run
    except BaseException:
        made = [d for d, _, _ in os.walk(root) if d not in before]
        for d in sorted(made, key=lambda d: d.count(os.sep), reverse=True) + [str(p) for p in missing]:
            with contextlib.suppress(OSError):  # a directory that is not empty was not this run's alone: it stays
                os.rmdir(d)
        raise


@contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """A temp path beside `path` (same suffix) to write; renamed onto `path` if the block succeeds, else removed.

    Inside `run_outputs()`, the rename waits for the run's commit.
    """
    run = current_run()
    if run is not None:
        tmp = run.stage(path, ready=False)
        try:
            with writing(path):
                yield tmp
        except BaseException:
            run.drop(path)
            raise
        run.done(path)
        return
    with run_outputs() as own:
        tmp = own.stage(path, ready=False)
        with writing(path):
            yield tmp
        own.done(path)
