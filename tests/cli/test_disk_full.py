"""A full or read-only file system under `dvsot generate` is one line and exit 1, with nothing replaced: a short
write of a --keep-frames frame, and Blender's render directory (/dev/shm) full or read-only. The file systems are
small tmpfs mounts (root only; skipped elsewhere)."""

import subprocess

import pytest
from synthetic import linear_path, tiny_scene

from dvsot.cli import main

pytestmark = pytest.mark.blender

SCENE = tiny_scene("tiny", {"shape": "cube", "size_m": 1.5, "material": {"color": [0.9, 0.9, 0.9]},
                            "trajectory": linear_path((-1, 0, 0), (1, 0, 0))}, threads=1)


@pytest.fixture
def tmpfs(tmp_path):
    """mount(size, read_only) -> a fresh tmpfs directory of that size under tmp_path, unmounted after the test."""
    mounted = []

    def mount(size: str = "64k", read_only: bool = False):
        d = tmp_path / f"fs{len(mounted)}"
        d.mkdir()
        opts = f"size={size}" + (",ro" if read_only else "")
        if subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(d)], capture_output=True).returncode:
            pytest.skip("cannot mount a tmpfs here (needs root)")
        mounted.append(d)
        return d

    yield mount
    for d in mounted:
        subprocess.run(["umount", str(d)], capture_output=True)


def generate_fails(tmp_path, capsys, extra: list[str], words: list[str]) -> None:
    """`dvsot generate` exits 1 with one line holding words; the old output keeps its bytes and no temp is left."""
    scene, out = tmp_path / "s.yaml", tmp_path / "out.h5"
    scene.write_text(SCENE)
    out.write_bytes(b"old output")
    assert main(["generate", str(scene), "-o", str(out), "--quiet", *extra]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in words), err
    assert out.read_bytes() == b"old output"
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("fs")) == ["out.h5", "s.yaml"]


def test_a_short_write_of_a_kept_frame_is_one_line_and_replaces_nothing(tmp_path, capsys, tmpfs):
    frames = tmpfs("64k") / "frames"  # room for three 160x120 float32 frames
    generate_fails(tmp_path, capsys, ["--keep-frames", str(frames)], [str(frames), "cannot write", "nothing"])
    assert not frames.exists() and not list(frames.parent.iterdir())


@pytest.mark.parametrize("read_only, words", [(False, "No space left on device"), (True, "Read-only file system")])
def test_a_full_or_read_only_render_directory_is_one_line_and_replaces_nothing(tmp_path, capsys, tmpfs, monkeypatch,
                                                                                read_only, words):
    import dvsot.render.blender.scene

    shm = tmpfs("64k", read_only=read_only)
    monkeypatch.setattr(dvsot.render.blender.scene, "RENDER_DIR", str(shm))
    generate_fails(tmp_path, capsys, [], [str(shm), words, "nothing was replaced"])
    assert not list(shm.iterdir())  # Blender's render directory removed
