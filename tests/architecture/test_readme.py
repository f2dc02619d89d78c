"""README's code blocks as written: each bash line runs here (the cheap ones) or passes its command's own parser.

Cheap lines (`--help`, `--dry-run`, `dvsot info`, `dvsot export`, `dvsot simulate`) run, in order, in a
directory laid out as `make demo` leaves one (the repository's scene files, `out/quickstart.h5`, here a tiny
simulated recording, and a `frames/` folder of tiny images). Every other line (renders, training, benchmarks) is
parsed by `dvsot`'s own argument parser on the exact argv, not run; its tracker names and `--option` keys are
checked against the registries. Every path into the repository that the page names must exist, and every flag a
comment names must be one of that command's flags. The Python block runs in test_public_api.py.
"""

from __future__ import annotations

import argparse
import functools
import glob
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
# first path components that are the repository's own folders; any other path (out/, data/, runs/) is the user's
REPO_FOLDERS = ("blender_scenes", "benchmarks", "docs", "dvsot", "sctn", "tests")
CHEAP_COMMANDS = ("info", "export", "simulate")
_FOLDERS = "|".join(REPO_FOLDERS)
_PATH = re.compile(rf"(?<![\w./-])((?:{_FOLDERS})/(?:[\w.*-]+/)*[\w.*-]*[\w*/])")


def fenced_blocks() -> list[tuple[str, str]]:
    """(language, text) of every fenced code block of README.md."""
    return re.findall(r"^```(\w*)\n(.*?)^```", README.read_text(encoding="utf-8"), re.S | re.M)


def bash_lines() -> list[tuple[str, str]]:
    """(command, comment) of every command line of README's bash blocks (comment-only and blank lines left out)."""
    out = []
    for lang, text in fenced_blocks():
        if lang != "bash":
            continue
        for line in text.replace("\\\n", " ").splitlines():
            parts = re.split(r"(?:^|\s)#\s", line, maxsplit=1)
            code, comment = parts[0].strip(), parts[1].strip() if len(parts) > 1 else ""
            if code:
                out.append((code, comment))
    return out


def expand(args: list[str], cwd: Path) -> list[str]:
    """The argv bash gives: a glob that matches is replaced by its sorted matches (relative to cwd); one that
    matches nothing stays as written."""
    out = []
    for arg in args:
        hits = sorted(glob.glob(arg, root_dir=cwd)) if glob.has_magic(arg) else []
        out += hits or [arg]
    return out


def repo_path_problems(text: str) -> list[str]:
    """The paths into the repository's own folders in `text` that name nothing there."""
    problems = []
    for path in _PATH.findall(text):
        if not glob.glob(path.rstrip("/"), root_dir=ROOT):
            problems.append(path)
    return problems


@functools.cache
def _parser() -> argparse.ArgumentParser:
    from dvsot.cli import build_parser

    return build_parser()


def _subparser(name: str) -> argparse.ArgumentParser:
    """The parser of `dvsot NAME`, or of `dvsot` itself where NAME is no command."""
    parser = _parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name] if name in sub.choices else parser


def _parse(argv: list[str], capsys) -> argparse.Namespace:
    """`dvsot`'s parser on argv; a refusal fails the test with the parser's own line."""
    try:
        return _parser().parse_args(argv)
    except SystemExit as exc:
        pytest.fail(f"README: dvsot {shlex.join(argv)}: refused by its parser (status {exc.code}): "
                    f"{capsys.readouterr().err.strip()}")


def _check_registries(args: argparse.Namespace, line: str) -> None:
    """Tracker names and `--option` keys that only the run would check."""
    from benchmarks.trackers import available_trackers

    for name in getattr(args, "tracker", None) or []:
        assert name in available_trackers(), f"README: {line}: unknown tracker {name!r}"
    if getattr(args, "protocol", None) == "stream":  # latency models against the trackers, as the run checks them
        from benchmarks.bench.stream_options import check_stream
        from dvsot.core.errors import UserError

        stream = {"latency": args.latency, "query_hz": args.query_hz, "window": args.stream_window,
                  "predictive": args.predictive}
        try:
            check_stream("stream", stream, args.tracker or [], [])
        except UserError as exc:
            pytest.fail(f"README: {line}: {exc}")
    for spec in getattr(args, "option", None) or []:
        tracker, _, rest = spec.partition(".")
        key, _, value = rest.partition("=")
        assert tracker in (args.tracker or []), f"README: {line}: --option {spec} names a tracker not in the run"
        if tracker != "sctn":
            pytest.fail(f"README: {line}: this test checks only sctn's --option keys; extend it for {tracker!r}")
        from pydantic import ValidationError

        from benchmarks.trackers.sctn import SCTNOptions
        from dvsot.scene import yaml_value

        try:
            SCTNOptions(**{key: yaml_value(value)})
        except ValidationError as exc:
            pytest.fail(f"README: {line}: --option {spec}: {' '.join(str(exc).split())}")


def _unknown_flags(argv: list[str], text: str) -> list[str]:
    """The --flags in `text` (a line's argv or comment) that its command does not have by that exact name (argparse
    would take a prefix of one)."""
    parser = _subparser(argv[0]) if argv and not argv[0].startswith("-") else _subparser("")
    known = set(parser._option_string_actions)
    return [f for f in re.findall(r"(?<![\w-])(--[a-z][\w-]*)", text) if f not in known]


@pytest.fixture
def demo_dir(tmp_path: Path) -> Path:
    """A directory as `make demo` leaves one: the repository's scenes, out/quickstart.h5 (a tiny recording of
    frames/, simulated instead of rendered: the renders are not what this test checks)."""
    import numpy as np
    from PIL import Image

    import dvsot

    (tmp_path / "blender_scenes").symlink_to(ROOT / "blender_scenes")
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(12):  # 12 frames at 1 kHz: one whole 10 ms segment
        image = np.zeros((24, 32), np.uint8)
        image[8:14, 2 + 2 * i:8 + 2 * i] = 255
        Image.fromarray(image).save(frames / f"{i:03d}.png")
    (tmp_path / "out").mkdir()
    dvsot.simulate_file(str(frames), str(tmp_path / "out" / "quickstart.h5"), fps=1000, progress=False)
    return tmp_path


def test_the_page_has_only_blocks_this_test_or_test_public_api_runs():
    languages = [lang for lang, _ in fenced_blocks()]
    assert set(languages) <= {"bash", "python"}, languages
    assert languages.count("python") == 1, "README: the one Python block is the python-api one"
    assert bash_lines()


def test_every_repository_path_the_page_names_exists():
    problems = repo_path_problems(README.read_text(encoding="utf-8"))
    assert not problems, f"README names repository paths that do not exist: {problems}"


def test_every_bash_line_runs_or_passes_its_parser(demo_dir, monkeypatch, capsys):
    from dvsot.cli import main

    monkeypatch.chdir(demo_dir)
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    for code, comment in bash_lines():
        words = shlex.split(code)
        if words[0] == "make":
            for target in words[1:]:
                assert re.search(rf"^{re.escape(target)}:", makefile, re.M), f"README: {code}: no Makefile target"
            continue
        assert words[0] == "dvsot", f"README: {code}: neither run nor checked by this test"
        argv = expand(words[1:], demo_dir)
        missing = [a for a in argv if repo_path_problems(a)]
        assert not missing, f"README: {code}: no such repository path {missing}"
        unknown = _unknown_flags(argv, shlex.join(argv))
        assert not unknown, f"README: {code}: flags the command lacks by these names: {unknown}"
        unknown = _unknown_flags(argv, comment)
        assert not unknown, f"README: {code}: its comment names flags the command lacks: {unknown}"
        if "--help" in argv or "--dry-run" in argv or argv[0] in CHEAP_COMMANDS:
            try:
                status = main(argv)
            except SystemExit as exc:  # --help
                status = exc.code
            assert status == 0, f"README: {code}: exit status {status}: {capsys.readouterr().err.strip()[-500:]}"
            made = [p.rstrip(";,.:)") for p in re.findall(r"(?<![\w/])out/\S+", comment)]
            absent = [p for p in made if not (demo_dir / p).exists()]
            assert not absent, f"README: {code}: its comment names outputs it did not write: {absent}"
        else:
            _check_registries(_parse(argv, capsys), code)


@pytest.mark.parametrize("line, problem", [
    ("dvsot bench --tracker rct --no-such-flag", "refused by its parser"),
    ("dvsot bench --tracker no_such_tracker", "unknown tracker"),
    ("dvsot bench --tracker sctn --option sctn.no_such_key=1", "no_such_key"),
    ("dvsot bench --tracker sctn --option sctn.reinit=onlin", "reinit"),
    ("dvsot bench --tracker rct --protocol stream --latency declared:cpu", "no latency under it"),
    ("dvsot train --model no_such_model -o runs/x.pt", "refused by its parser"),
])
def test_a_bad_line_fails_the_check(line, problem, capsys):
    with pytest.raises((pytest.fail.Exception, AssertionError), match=problem):
        _check_registries(_parse(shlex.split(line)[1:], capsys), line)


def test_a_missing_repository_path_or_flag_is_found():
    assert repo_path_problems("`blender_scenes/no_such.yaml`, docs/results.md") == ["blender_scenes/no_such.yaml"]
    assert repo_path_problems("blender_scenes/*.yaml sctn/checkpoints/") == []
    assert _unknown_flags(["info", "out/x.h5"], "--json for scripts, --jsn") == ["--jsn"]
    assert _unknown_flags(["train"], "train --max-minute 15") == ["--max-minute"]  # argparse takes the prefix
