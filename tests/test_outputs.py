"""Output-path checks every command runs before it starts work."""

import pytest

from dvsot.errors import UserError
from dvsot.outputs import output_dir, output_file


def test_output_file_accepts_a_new_or_existing_file(tmp_path):
    assert output_file(tmp_path / "a.h5", "-o") == tmp_path / "a.h5"
    (tmp_path / "b.h5").write_text("x")
    assert output_file(tmp_path / "b.h5", "-o", inputs=[tmp_path / "c.yaml"]) == tmp_path / "b.h5"


@pytest.mark.parametrize("make, words", [
    (lambda d: (d / "sub").mkdir() or d / "sub", "-o names a directory"),
    (lambda d: d / "nope" / "a.h5", "does not exist"),
])
def test_output_file_refuses(tmp_path, make, words):
    with pytest.raises(UserError, match=words):
        output_file(make(tmp_path), "-o")


def test_output_file_refuses_an_input(tmp_path):
    src = tmp_path / "scene.yaml"
    src.write_text("name: x\n")
    with pytest.raises(UserError, match="would overwrite an input file"):
        output_file(tmp_path / "." / "scene.yaml", "-o", inputs=[tmp_path / "other.yaml", src])


def test_output_dir(tmp_path):
    assert output_dir(tmp_path / "new" / "deeper", "--out-dir") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists()  # nothing made before there is output
    (tmp_path / "f").write_text("x")
    with pytest.raises(UserError, match="names a file"):
        output_dir(tmp_path / "f", "--out-dir")
    with pytest.raises(UserError, match="is a file, not a directory"):
        output_dir(tmp_path / "f" / "sub", "--out-dir")
