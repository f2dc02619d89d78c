"""Dataset files' ground truth and challenge tags in the per-sequence layouts of the GOT-10k, LaSOT and VOT toolkits.

A toolkit's frame is a segment: line i of every file is segment i, its ground truth at the segment's end (what
`dvsot bench` scores and writes its per-sequence results against). Sequences are named as bench names their
result files (dvsot.core.file_names.file_stem of the file's name). The tags come from dvsot.dataset.tags; a tag
file the dataset file cannot decide (no visibility, no truncation: a recording, an older file) is left out and a
TagsLeftOut warning names it. Boxes are x,y,w,h (pixels, top-left corner), `nan,nan,nan,nan` where the target has
no box on the sensor. The events stay in the dataset files (or `dvsot export FILE -o x.aedat4` per sequence).

- got10k: `list.txt`; `<seq>/groundtruth.txt`, `absence.label`, `cover.label` (0-8), `cut_by_image.label` (one
  integer per line) and `meta_info.ini` (`[METAINFO]`, then `key: value` lines), as got10k's GOT10k dataset reads
  a subset directory (`GOT10k(root, subset=<the directory's name>, return_meta=True)`).
- lasot: `<seq>/<seq>-1/groundtruth.txt`, `full_occlusion.txt` and `out_of_view.txt` (0/1 comma-separated on one
  line) and `nlp.txt` (the target's name), LaSOT's `<category>/<category>-<index>/` tree.
- vot: `list.txt`; `<seq>/sequence` (key=value: name, fps, format, length, width, height), `groundtruth.txt`,
  one `<tag>.tag` per tag (`1` or `0` per line) and `visibility.value`, `truncation.value` (one number per line),
  as the VOT toolkit's read_sequence reads a sequence directory without its images.

The directory holds one export's files: a manifest (`.dvsot_export.json`, hidden: LaSOT's reader lists every
visible entry as a sequence) names them, and an export again replaces them all at once
(dvsot.runtime.outputs.owned_run).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from dvsot.core.errors import UserError, label
from dvsot.core.file_names import file_stem

if TYPE_CHECKING:  # numpy is imported where it is used: the command's flags name LAYOUTS without it
    import numpy as np

    from dvsot.dataset import Dataset

LAYOUTS = ("got10k", "lasot", "vot")
MANIFEST = ".dvsot_export.json"


class TagsLeftOut(UserWarning):
    """A dataset file's ground truth cannot decide some of a layout's tag files: they are left out."""


def _box_lines(xywh: np.ndarray) -> str:
    """One x,y,w,h line per row (float32 values that read back exactly; nan where there is no box)."""
    import numpy as np

    return "".join(",".join(f"{v:.9g}" for v in row) + "\n" for row in np.asarray(xywh, np.float32).tolist())


def _lines(values: np.ndarray) -> str:
    """One value per line: flags and labels as integers, shares as float32 values that read back exactly."""
    import numpy as np

    a = np.asarray(values)
    if a.dtype == bool or a.dtype.kind in "iu":
        return "".join(f"{int(v)}\n" for v in a.tolist())
    return "".join(f"{v:.9g}\n" for v in a.astype(np.float32).tolist())


def _one_line(text: str) -> str:
    """Free text (a target's name) on one line: whitespace runs, newlines included, become one space."""
    return " ".join(str(text).split()) or "target"


def sequence_texts(ds: Dataset, layout: str) -> tuple[dict[str, str], list[str]]:
    """({path relative to the sequence's directory: text}, [the tag files left out]) of one opened dataset file."""
    import numpy as np

    from dvsot.dataset.tags import cover_label, segment_tags

    box, vis, trunc, absent = (ds.segment_boxes(), ds.segment_visibility(), ds.segment_truncation(),
                               ds.segment_absent())
    tags = segment_tags(ds)
    target = next((r["name"] for r in ds.objects or () if r["role"] == "target"), "target")
    fps = f"{1e6 / ds.segment_us:g}"
    files: dict[str, str] = {"groundtruth.txt": _box_lines(box)}
    wanted: dict[str, np.ndarray | None] = {}
    if layout == "got10k":
        wanted["absence.label"] = tags.get("absent")
        wanted["cover.label"] = None if vis is None else cover_label(vis, absent, trunc)
        wanted["cut_by_image.label"] = tags.get("cut_by_image")
        files["meta_info.ini"] = ("[METAINFO]\n" f"object_class: {_one_line(target)}\n"
                                  f"resolution: ({ds.width}, {ds.height})\n" f"anno_fps: {fps}Hz\n")
    elif layout == "lasot":
        wanted.update({f"{name}.txt": tags.get(name) for name in ("full_occlusion", "out_of_view")})
        files["nlp.txt"] = _one_line(target) + "\n"
    elif layout == "vot":
        from dvsot.dataset.tags import TAGS

        wanted.update({f"{name}.tag": tags.get(name) for name in TAGS})
        wanted["visibility.value"], wanted["truncation.value"] = vis, trunc
        # length, width and height: the toolkit takes them from the frames' images where the file does not say
        files["sequence"] = (f"name={file_stem(ds.name)}\nfps={fps}\nformat=default\nlength={len(box)}\n"
                             f"width={ds.width}\nheight={ds.height}\n")
    else:
        raise ValueError(f"layout {layout!r}: expected one of {', '.join(LAYOUTS)}")
    left_out = [name for name, values in wanted.items() if values is None]
    for name, values in wanted.items():
        if values is None:
            continue
        if layout == "lasot":  # LaSOT: every frame's flag on one comma-separated line
            files[name] = ",".join(str(int(v)) for v in np.asarray(values).tolist()) + "\n"
        else:
            files[name] = _lines(values)
    return files, left_out


def sequence_dir(name: str, layout: str) -> Path:
    """A sequence's directory inside a layout's root: <stem>, or LaSOT's <stem>/<stem>-1."""
    stem = file_stem(name)
    return Path(stem, f"{stem}-1") if layout == "lasot" else Path(stem)


def export_layout(
    specs: str | os.PathLike | list,
    out_dir: str | os.PathLike,
    layout: str,
    labels: Mapping[str, str] | None = None,
    split: str | None = None,
) -> list[Path]:
    """Write the ground truth and tags of the dataset files that specs name (a file, directory, glob or a list of
    them; split: only those of one split) into out_dir in a toolkit's layout (LAYOUTS); the files written.

    Checked before anything is written (UserError): the layout, every dataset file, two files whose names give one
    sequence directory, out_dir (a directory holding only an earlier export's files). labels: how messages name
    out_dir and layout (a command's flags)."""
    import warnings

    from dvsot.dataset import Dataset, find_datasets
    from dvsot.runtime.outputs import owned_run, replacing

    if layout not in LAYOUTS:
        raise UserError(f"{label('layout', labels)} {layout!r}: expected one of {', '.join(LAYOUTS)}")
    flag = label("out_dir", labels)
    files = find_datasets(specs, split=split, verify=False)  # the events are not read: opening checks the truth
    names: dict[str, tuple[str, Path]] = {}
    texts: dict[Path, str] = {}
    notes = []
    for f in files:
        with Dataset(f) as ds:
            stem = file_stem(ds.name)
            if stem.casefold() in names:
                other, where = names[stem.casefold()]
                raise UserError(f"{f}: sequence '{ds.name}' and '{other}' ({where}) would share the directory "
                                f"{sequence_dir(ds.name, layout)}; rename one")
            names[stem.casefold()] = (ds.name, f)
            seq, left_out = sequence_texts(ds, layout)
            missing = [name for name, values in (("visibility", ds.segment_visibility()),
                                                 ("truncation", ds.segment_truncation())) if values is None]
        texts.update({sequence_dir(ds.name, layout) / name: text for name, text in seq.items()})
        if left_out:
            notes.append(f"{f}: holds no {' or '.join(missing)} per segment, so {stem}'s {', '.join(left_out)} "
                         "are left out")
    if layout in ("got10k", "vot"):
        texts[Path("list.txt")] = "".join(sequence_dir(ds_name, layout).as_posix() + "\n"
                                          for ds_name, _ in names.values())
    for note in notes:
        warnings.warn(note, TagsLeftOut, stacklevel=2)
    written = []
    with owned_run(out_dir, flag, list(texts), MANIFEST):
        for rel, text in texts.items():
            path = Path(out_dir) / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            with replacing(path) as tmp:
                Path(tmp).write_text(text)
            written.append(path)
    return written
