"""The checks a run makes before it writes anything, and again before it places its dataset: the
output's place and name, the files already there (a dataset of the same scene or of another, an
unfinished run's journal and whether it can be resumed), the room it needs (memory, disk, the
file-size limit). Each refusal is a StoreError naming the file and what to do."""
from __future__ import annotations

import errno
import os
import shutil
import stat
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import FileBusy, InputError, StoreError, WriteFailed, why_os_error
from ..scene import Scene, load_scene_text
from ..store.journal import (RESTART, Journal, discard_path, lock_path, own_files_problem, partial_path,
                             scene_differences)
from ..store.read import check_journal_files, file_kind
from .plan import extra_shape

def mib(n: float) -> str:
    return f"{n / 2**20:.3g} MiB"


def check_existing(scene: Scene, final: Path, resume: bool, restart: bool, target: int, n_chunks: int,
                    overwrite: bool = False) -> bool:
    """Refuse what would mix runs or lose results: an unfinished run without --resume/--restart,
    a resume with another scene, an existing dataset of another scene (or a file mechsweep did
    not write) without ``overwrite``. True when ``resume`` finds the run already finished."""
    part = partial_path(final)
    if (why := own_files_problem(final)) is not None:  # a user's file in the journal: never removed
        raise StoreError(why)
    check_journal_files(part, contents=not restart)  # --restart discards what the folder holds
    if part.exists() and not (resume or restart):
        raise StoreError(f"an unfinished run of this output exists: {part}; continue it with --resume "
                         "or discard it with --restart")
    same = _holds_same_scene(final, scene, overwrite)  # None: no dataset there (or an empty file)
    if resume and not part.exists() and same:
        if (why := _dataset_sources_changed(final, scene)) is not None:
            raise StoreError(why)
        return True
    if part.exists() and not restart:
        journal = Journal.read(part)
        canonical = scene.canonical()
        if not journal.empty and same_scene({"scene_canonical": journal.meta["scene_canonical"],
                                             "scene": journal.meta.get("scene"),
                                             "scene_folder": journal.meta.get("attrs", {}).get("scene_folder")},
                                            scene):
            canonical = journal.meta["scene_canonical"]  # the same scene, perhaps in an older version's form
        if not journal.empty and (why := journal.matches(canonical, target, n_chunks)) is not None:
            raise StoreError(why)
        if not journal.empty and (why := _journal_attrs_problem(journal, scene)) is not None:
            raise StoreError(why)
        if not journal.empty and (why := _journal_sources_changed(journal, scene)) is not None:
            raise StoreError(why)  # the same scene, but its model's code changed since the run began
    return False


def _journal_attrs_problem(journal: Journal, scene: Scene) -> str | None:
    """Why the attributes an unfinished run's journal gives its dataset do not describe ``scene``
    (its run.json edited; a journal of format 2 has no checksum to tell), or None: the model, the
    outputs and the solver settings, which the scene determines."""
    import json

    attrs = journal.meta["attrs"]
    expected = {"model": scene.model.name, "outputs": " ".join(scene.outputs)}
    if scene.solver is not None:
        expected.update({f"solver_{k}": v for k, v in scene.solver.as_dict().items()})
    expected = json.loads(json.dumps(expected))  # as run.json holds them
    for key in sorted(set(expected) | {k for k in attrs if k.startswith("solver_")}):
        if key not in attrs or key not in expected or attrs[key] != expected[key]:
            stored = repr(attrs[key]) if key in attrs else "missing"
            wanted = repr(expected[key]) if key in expected else "none"
            return (f"{journal.folder / 'run.json'} gives the dataset the attribute {key} = {stored}, the scene "
                    f"{wanted}: the journal was edited; {RESTART}")
    return None


def _journal_sources_changed(journal: Journal, scene: Scene) -> str | None:
    """Why the unfinished run ``journal`` cannot be resumed with the model's current sources (the
    model file, the user modules it imports, the packages they use, mechsweep: model/sources.py), or
    None when they are those it began with. A journal that records none (written by a version before
    the record) is refused too: what its chunks were computed from cannot be checked."""
    from ..model import sources

    attrs = journal.meta.get("attrs") if isinstance(journal.meta, dict) else None
    stored = attrs.get("dependencies") if isinstance(attrs, dict) else None
    if stored is None:
        version = attrs.get("mechsweep_version", "?") if isinstance(attrs, dict) else "?"
        return (f"{journal.folder} was started by mechsweep {version}, which did not record the sources its "
                "results depend on (the model file, the modules it imports, mechsweep's own): its chunks cannot "
                "be checked against the current ones; start over with --restart")
    changed = sources.differences(stored, sources.record(scene.model), scene.base or None)
    if not changed:
        return None
    return (f"cannot resume {journal.folder}: {'; '.join(changed)}; start over with --restart, or restore "
            f"{'them' if len(changed) > 1 else 'it'} and resume")


def _dataset_sources_changed(final: Path, scene: Scene) -> str | None:
    """Why ``--resume`` cannot take the finished dataset ``final`` as this run's result: it was
    computed from other sources than the model's current ones (None: the same, or a dataset of a
    version that recorded none, which is taken as it is: nothing is computed)."""
    import h5py

    from ..model import sources

    try:
        with h5py.File(final, "r") as f:
            stored = _attr_text(f.attrs["dependencies"]) if "dependencies" in f.attrs else None
    except Exception:  # damaged internals were refused by _holds_same_scene's check already
        return None
    if stored is None:
        return None
    changed = sources.differences(stored, sources.record(scene.model), scene.base or None,
                                  since="this dataset was computed")
    if not changed:
        return None
    return (f"{final} is finished, but computed from other sources: {'; '.join(changed)}; compute it again "
            f"with `mechsweep run` without --resume (the dataset is replaced), or restore "
            f"{'them' if len(changed) > 1 else 'it'}")


def _holds_same_scene(final: Path, scene: Scene, overwrite: bool) -> bool | None:
    """Whether the dataset at ``final`` is a run of ``scene``; None when there is no dataset
    (absent or an empty file). A dataset of another scene, or a file that is not a mechsweep
    dataset, is refused unless ``overwrite`` (then False)."""
    if not final.exists() or final.stat().st_size == 0:
        return None
    try:
        attrs = _stored_run_attrs(final)
    except FileBusy as exc:  # never replaced, whatever the flags: that process's writes would be lost
        raise FileBusy(final, exc.holder, doing="a run would replace it and the writes of that process "
                       "would be lost: wait until it closes the file (or stop it), or write elsewhere with -o") from None
    except StoreError as exc:
        if overwrite:
            return False
        raise StoreError(f"{exc}; a run would replace it: use --overwrite to replace it anyway, "
                         "or choose another path with -o") from None
    same = None if attrs is None else same_scene(attrs, scene)
    if same is None and not overwrite:
        raise StoreError(f"{final} is a mechsweep benchmark dataset, not a run; use --overwrite to replace it, "
                         "or choose another path with -o")
    if same is False and not overwrite:
        what = scene_differences(str(attrs.get("scene_canonical", "")), scene.canonical(), then="in the stored run")
        raise StoreError(f"{final} holds a finished run of a different scene ("
                         + (what or "model, outputs, axes, fixed values or solver settings differ")
                         + "); use --overwrite to replace it, or choose another path with -o")
    return bool(same)


def _stored_same_scene(final: Path, scene: Scene) -> bool | None:
    """Whether the dataset at ``final`` is a run of ``scene`` (None: a benchmark's dataset), from its
    attributes alone (read with h5py: a re-run does not pay for opening the dataset with xarray).
    StoreError when it is not a dataset mechsweep wrote."""
    attrs = _stored_run_attrs(final)
    return None if attrs is None else same_scene(attrs, scene)


def _stored_run_attrs(final: Path) -> dict | None:
    """The scene attributes of the run stored at ``final`` (None: a benchmark's dataset). StoreError
    when it is not a dataset mechsweep wrote, FileBusy while another process writes it."""
    import h5py

    from ..store.read import RUN_ATTRS, check_dataset_file, is_lock_error, lock_holder

    check_dataset_file(final)  # a regular HDF5 file with a run's (or a benchmark's) attributes
    try:
        with h5py.File(final, "r") as f:
            keys = ("scene_canonical", "scene", "scene_folder") + RUN_ATTRS
            attrs = {k: _attr_text(f.attrs[k]) for k in keys if k in f.attrs}
            run = all(a in attrs for a in RUN_ATTRS) and "status" in f
    except Exception as exc:  # damaged internals: as check_dataset_file says it
        if is_lock_error(exc):  # another process opened it for writing since check_dataset_file
            raise FileBusy(final, lock_holder(final)) from None
        raise StoreError(f"{final} is not a mechsweep dataset: it is an HDF5 file that cannot be read "
                         f"({str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__})") from None
    return attrs if run else None


def _attr_text(value):
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    if isinstance(value, np.ndarray) and value.size == 1:
        return _attr_text(value.ravel()[0])
    return value


def same_scene(attrs: Mapping, scene: Scene) -> bool:
    """Whether a dataset's attributes describe a run of ``scene``: its stored canonical form equals
    the scene's, or its stored scene text, read by this version, has the same canonical form
    (the form may change between versions; the text stays the user's)."""
    if scene.same_as(attrs.get("scene_canonical")):
        return True
    text = attrs.get("scene")
    if not isinstance(text, str):
        return False
    try:
        return load_scene_text(text, label="stored scene", base=attrs.get("scene_folder") or None,
                               ).canonical() == scene.canonical()
    except InputError:
        return False


def output_state(final: Path) -> tuple | None:
    """What is at ``final`` (the entry itself, a link not followed: device, inode, kind, size, times),
    None when nothing is."""
    try:
        s = os.lstat(final)
    except (FileNotFoundError, NotADirectoryError):
        return None
    return (s.st_dev, s.st_ino, s.st_mode, s.st_size, s.st_mtime_ns, s.st_ctime_ns)


def placing_problem(final: Path, scene: Scene, before: tuple | None) -> str | None:
    """Why the finished dataset may not replace what is at ``final`` now, or None: nothing there,
    what the checks accepted when the run started (``before``), or a dataset of the same scene.
    Anything else came while the run computed and is not the run's to replace, whatever
    --overwrite said about the file of the start."""
    now = output_state(final)
    if now is None or now == before:
        return None
    mode = now[2]
    if stat.S_ISREG(mode):
        try:
            same = _stored_same_scene(final, scene)
        except StoreError as exc:
            what = str(exc).replace(f"{final} is ", "", 1)
        else:
            if same:
                return None
            what = ("a mechsweep benchmark dataset" if same is None else
                    "a dataset of a different scene")
    else:
        what = file_kind(mode)
    part = partial_path(final)
    return (f"{final} {'appeared' if before is None else 'changed'} while the run computed ({what}); a run replaces "
            "only the file its checks accepted when it started, or a dataset of the same scene, so it was left as "
            f"it is. The finished chunks are kept in {part}: move {final} away, then run again with --resume (it "
            "only assembles the dataset)")


def check_output_place(final: Path) -> None:
    """Refuse an output inside a run's journal folder (``NAME.partial/``, ``NAME.partial.discard/``),
    where the run of NAME would find a file it did not write, or named as another output's journal
    or lock (``NAME.partial``, ``.NAME.lock``). Links are followed: the folder the file is in counts."""
    suffixes = (".partial", ".partial.discard")
    folder = Path(os.path.realpath(final.parent))
    for f in (folder, *folder.parents):
        if f.name.endswith(suffixes):
            owner = f.name[:-len(".partial")] if f.name.endswith(".partial") else f.name[:-len(".partial.discard")]
            raise StoreError(f"output path {final} is inside {f}, the journal folder of an unfinished run of "
                             f"{f.parent / owner} (a run keeps its finished chunks there and removes the folder "
                             "when it ends); choose another path with -o")
    name = final.name
    if name.endswith(suffixes) or (name.startswith(".") and name.endswith(".lock") and len(name) > len("..lock")):
        raise StoreError(f"output path {final}: a name ending in .partial or .partial.discard, or of the form "
                         ".NAME.lock, is the one mechsweep gives the journal or the lock of another output; "
                         "choose another name")


def file_size_limit() -> int | None:
    """The process's file-size limit in bytes (``ulimit -f``); None when unlimited, or where the
    system has no such limit (no ``resource`` module: Windows)."""
    try:
        import resource
    except ImportError:
        return None
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else soft


def check_file_limit(scene: Scene, final: Path) -> None:
    """Refuse, before any file is made, a run whose dataset cannot fit under the process's file-size
    limit (``ulimit -f``). Counted are only the float outputs, which are stored uncompressed: the
    dataset is at least that large, so no run that would fit is refused."""
    soft = file_size_limit()
    if soft is None:
        return
    least = _least_bytes(scene)
    if least > soft:
        raise StoreError(f"file size limit reached (ulimit -f): the dataset {final} needs at least {mib(least)}, "
                         f"the limit is {mib(soft)}; raise the limit (ulimit -f unlimited) or make the grid coarser")


def check_free_space(scene: Scene, tmp: Path, written: int = 0) -> None:
    """Before the assembly: refuse at once when the disk cannot hold even the dataset's float
    outputs (a lower bound of its size), less the ``written`` bytes of it already on the disk,
    instead of failing part way."""
    try:
        free = shutil.disk_usage(tmp.parent).free
    except OSError:
        return
    least = _least_bytes(scene) - written
    if least > free:
        raise WriteFailed(tmp, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))


def _least_bytes(scene: Scene) -> int:
    return 8 * scene.n_points * _values_per_point(scene)


def _values_per_point(scene: Scene) -> int:
    return sum(int(np.prod(extra_shape(scene, name), dtype=np.int64)) for name in scene.outputs)


def existing_ancestor(path: Path) -> Path:
    """The nearest folder (or file) on the way up from ``path`` that exists."""
    path = Path(os.path.abspath(path))
    while not os.path.lexists(path) and path != path.parent:
        path = path.parent
    return path


def check_target(final: Path, create_folder: bool = False) -> None:
    """Refuse an output path that cannot work, before any computation. ``create_folder``: the
    folder of ``final`` is missing and will be created (then its nearest existing ancestor must
    be a writable folder)."""
    if "\0" in str(final):
        raise StoreError(f"output path {str(final)!r} contains a NUL character")
    try:
        name_max = os.pathconf(final.parent if final.parent.is_dir() else ".", "PC_NAME_MAX")
    except (AttributeError, OSError):
        name_max = 255
    longest = len(os.fsencode(discard_path(final).name))  # the longest name a run gives its files
    if longest > name_max:
        raise StoreError(f"file name {final.name[:40]}... is too long: {longest} bytes with the '.partial.discard' "
                         f"suffix a run uses, at most {name_max} allowed")
    try:
        final.stat()
    except (FileNotFoundError, NotADirectoryError):
        pass
    except OSError as exc:  # e.g. a path longer than the system allows, a folder on the way not searchable
        shown = str(final) if len(str(final)) <= 80 else str(final)[:80] + "..."
        raise StoreError(f"output path {shown}: {why_os_error(exc.errno, exc.strerror)}") from None
    if final.is_dir():
        raise StoreError(f"output path {final} is a directory; give a file path such as {final / 'run.h5'}")
    if os.path.lexists(final) and not final.is_file():
        raise StoreError(f"output path {final} is {_kind(final)}, not a regular file; a run writes only a "
                         "new file or replaces a dataset: choose another path with -o")
    for path, want, ok in ((lock_path(final), "a file", os.path.isfile),
                           (discard_path(final), "a folder", os.path.isdir)):
        if os.path.lexists(path) and not ok(path):
            raise StoreError(f"{path} (the run's {'lock' if want == 'a file' else 'journal being deleted'}) is "
                             f"{_kind(path)}, not {want} mechsweep made; move it away or choose another path with -o")
    parent = final.parent
    if create_folder and not os.path.lexists(parent):
        base = existing_ancestor(parent)
        if not base.is_dir():
            raise StoreError(f"{base} (in output path {final}) is {_kind(base)}, not a folder; the folder {parent} "
                             "cannot be created there: choose another path with -o")
        if not _writable(base):
            raise StoreError(f"cannot create the folder {parent} for output {final}: {base} is not writable "
                             "(permission denied)")
        return
    if parent.exists() and not parent.is_dir():
        raise StoreError(f"{parent} (in output path {final}) is a file, not a folder; choose another path with -o")
    if not parent.is_dir():
        raise StoreError(f"the folder {parent} for output {final} does not exist; create it first "
                         f"(mkdir -p {parent}) or choose another path with -o")
    if not _writable(parent):
        raise StoreError(f"cannot write into {parent}: permission denied (read-only folder)")
    if final.exists() and not _writable(final):
        raise StoreError(f"{final} exists and is read-only")
    if final.is_file() and final.stat().st_size > 0:
        with open(final, "rb") as f:
            magic = f.read(8)
        if magic != b"\x89HDF\r\n\x1a\n":
            raise StoreError(f"{final} exists and is not an HDF5 dataset; it would be overwritten: "
                             "choose another path with -o")


# Memory a chunk needs, in units of its output arrays: the chunk being computed (outputs and the
# model's scratch of the same size, e.g. a simulation's trajectory samples) and the previous
# chunk waiting to be written.
CHUNK_MEMORY_FACTOR = 3


def bytes_per_point(scene: Scene) -> int:
    """Bytes of one grid point before compression: every requested output (with its extra
    dimensions, float64), status (int8), and for integrated outputs n_steps and n_rhs (int64).
    Only the integer variables are compressed, so the file is at most this size per point."""
    return 8 * _values_per_point(scene) + 1 + (16 if scene.solver is not None else 0)


def check_size(scene: Scene, final: Path, chunk_points: int, saved: int) -> None:
    """Refuse, before any file is made, a run whose chunk does not fit the available memory or
    whose files do not fit the free disk space, with the sizes involved. Until the end a run needs
    twice the dataset's size, less the ``saved`` bytes an unfinished run already holds: the journal
    of finished chunks and the dataset assembled from it."""
    per_point = bytes_per_point(scene)
    chunk_need = CHUNK_MEMORY_FACTOR * per_point * chunk_points
    available = available_memory()
    if available is not None and chunk_need > available:
        raise StoreError(f"a chunk of {chunk_points:,} points would need about {size_text(chunk_need)} of memory, "
                         f"{size_text(available)} is available; set a smaller [storage] chunk_size "
                         f"(at most {max(1, available // (CHUNK_MEMORY_FACTOR * per_point)):,} points)")
    data = per_point * scene.n_points
    need = max(0, 2 * data - saved)
    free = shutil.disk_usage(existing_ancestor(final.parent)).free + (final.stat().st_size if final.exists() else 0)
    if need > free:
        raise StoreError(f"the dataset {final} would need {size_text(data)} ({scene.n_points:,} points x "
                         f"{size_text(per_point)}), and {size_text(need)} free until the run ends (its journal of "
                         f"finished chunks and the dataset); its disk has {size_text(free)} free; make the grid "
                         "coarser, ask for fewer outputs, or write elsewhere with -o")


def saved_bytes(final: Path) -> int:
    """Bytes of finished chunks an unfinished run of ``final`` holds (0 if none)."""
    chunks = partial_path(final) / "chunks"
    try:
        return sum(e.stat().st_size for e in os.scandir(chunks))
    except OSError:  # no journal, or it went away meanwhile
        return 0


def available_memory() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def size_text(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} PB"


def _kind(path: Path) -> str:
    """What a file system entry is, for a message."""
    try:
        return file_kind(os.stat(path).st_mode)
    except OSError:
        return "a broken link"


def _writable(path: Path) -> bool:
    """Write permission, and not marked read-only (root passes os.access even then)."""
    return os.access(path, os.W_OK) and bool(path.stat().st_mode & 0o222)
