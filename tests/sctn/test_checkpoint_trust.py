"""Checkpoints are checked, not trusted: a digest of the weights is written with them and checked on load (with the
zip's CRCs), non-finite weights are refused on save and on load, a training whose loss turns NaN stops with one line
and writes nothing, and the shipped checkpoints still load."""

import shutil
import sys
import warnings
import zipfile
from pathlib import Path

import pytest
import torch

from dvsot.cli import main
from dvsot.core.errors import RunError, UserError
from sctn.checkpoint import (
    DIGEST_KEY,
    UndigestedCheckpointWarning,
    default_checkpoint_path,
    load_checkpoint,
    metadata_path,
    save_checkpoint,
    shipped_checkpoint_path,
    weights_digest,
)
from sctn.network import SCTN, NetworkConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.cli.test_bench_command import make  # noqa: E402
from tests.cli.test_train_command import TINY, data, snapshot  # noqa: E402,F401  (data: the module's dataset fixture)

torch.set_num_threads(1)
SMALL = NetworkConfig(channels=(2, 2, 2), fc=(4, 4))


def shipped() -> list[tuple[Path, str]]:
    """(checkpoint, kind) of every checkpoint shipped with the packages."""
    from benchmarks.trackers.siamfc.model import default_siamfc_path
    from benchmarks.trackers.trained_here import default_path
    from sctn.ann import default_twin_path

    return [(default_checkpoint_path(), "sctn"), (shipped_checkpoint_path("varied"), "sctn"),
            (default_twin_path(), "sctn_ann"), (default_siamfc_path(), "siamfc"),
            *[(default_path(k), k) for k in ("goturn", "siamrpn", "siammask", "ocean", "automatch")]]


# the shipped SiamFC was written before digests: its .json holds the digest of its unchanged weights; the others
# were written with the digest in the .pt itself
DIGEST_IN_PT = {"sctn_dvsot21.pt": True, "sctn_dvsot21_varied.pt": True, "sctn_ann_dvsot21.pt": True,
                "siamfc_dvsot21.pt": False, "siamrpn_dvsot21.pt": True, "siammask_dvsot21.pt": True,
                "ocean_dvsot21.pt": True, "automatch_dvsot21.pt": True, "goturn_dvsot21.pt": True}


def bench_refuses(tmp_path, capsys, ckpt: Path, words: list[str]) -> None:
    """`dvsot bench --tracker sctn --checkpoint ckpt` exits 2 with one line holding words, writing nothing."""
    make(tmp_path / "a.h5")
    before = snapshot(tmp_path)
    argv = ["bench", "--tracker", "sctn", "--data", str(tmp_path / "a.h5"), "--checkpoint", str(ckpt),
            "--out", str(tmp_path / "out"), "--jobs", "1", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and all(w in err[0] for w in [str(ckpt), *words]), err
    assert snapshot(tmp_path) == before


def flip_weight_bytes(pt: Path, member_index: int = 0) -> None:
    """Flip three bytes in the middle of one stored weight tensor of a zip-format .pt, in place."""
    raw = bytearray(pt.read_bytes())
    with zipfile.ZipFile(pt) as z:
        members = [i for i in z.infolist() if "/data/" in i.filename and i.file_size >= 16]
        tensor = z.read(members[member_index])
    at = raw.find(tensor) + len(tensor) // 2
    for k in range(3):
        raw[at + k] ^= 0x5A
    pt.write_bytes(bytes(raw))


def test_saved_checkpoints_carry_the_digest_of_their_weights(tmp_path):
    model = SCTN(SMALL)
    p = save_checkpoint(tmp_path / "m.pt", model, {})
    digest = weights_digest(model.state_dict())
    assert torch.load(p, weights_only=True)["meta"][DIGEST_KEY] == digest
    import json
    assert json.loads(metadata_path(p).read_text())[DIGEST_KEY] == digest
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded, meta = load_checkpoint(p)
    assert weights_digest(loaded.state_dict()) == digest


def test_flipped_bytes_in_a_weight_tensor_are_refused(tmp_path, capsys):
    """The shipped checkpoint (with its .json) with three bytes flipped inside a tensor: bench exits 2."""
    ckpt = tmp_path / "ck" / "sctn.pt"
    ckpt.parent.mkdir()
    shutil.copy(default_checkpoint_path(), ckpt)
    shutil.copy(metadata_path(default_checkpoint_path()), metadata_path(ckpt))
    flip_weight_bytes(ckpt)
    bench_refuses(tmp_path, capsys, ckpt, ["damaged SCTN checkpoint"])


def test_changed_weights_with_valid_crcs_are_refused_by_the_digest(tmp_path):
    """Weights changed and saved again by torch (valid zip CRCs) no longer match the digest written with them."""
    p = save_checkpoint(tmp_path / "m.pt", SCTN(SMALL), {})
    blob = torch.load(p, weights_only=True)
    blob["state_dict"]["convs.0.weight"][0, 0, 0, 0] += 1e-3
    torch.save(blob, p)
    with pytest.raises(UserError, match="do not match their weights_sha256 digest"):
        load_checkpoint(p)


def test_non_finite_weights_are_refused_on_load(tmp_path, capsys):
    """A NaN checkpoint, even one whose digest fits its NaNs, is no checkpoint to score."""
    (tmp_path / "ck").mkdir()
    p = save_checkpoint(tmp_path / "ck" / "m.pt", SCTN(SMALL), {})
    blob = torch.load(p, weights_only=True)
    blob["state_dict"] = {k: torch.full_like(v, float("nan")) for k, v in blob["state_dict"].items()}
    blob["meta"][DIGEST_KEY] = weights_digest(blob["state_dict"])
    torch.save(blob, p)
    metadata_path(p).unlink()
    bench_refuses(tmp_path, capsys, p, ["non-finite values"])


def test_non_finite_weights_are_refused_on_save(tmp_path):
    model = SCTN(SMALL)
    with torch.no_grad():
        next(model.parameters())[0].fill_(float("inf"))
    (tmp_path / "m.pt").write_bytes(b"old")
    with pytest.raises(RunError, match="not written.*non-finite"):
        save_checkpoint(tmp_path / "m.pt", model, {})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pt"] and (tmp_path / "m.pt").read_bytes() == b"old"


def test_a_diverging_training_stops_with_one_line_and_writes_nothing(data, tmp_path, capsys, monkeypatch):  # noqa: F811
    """A loss that turns NaN (as --lr 1e308 makes it) stops `dvsot train`: exit 1, one line, -o untouched."""
    import sctn.training.snn

    real = sctn.training.snn.batch_loss
    monkeypatch.setattr(sctn.training.snn, "batch_loss", lambda *a, **k: real(*a, **k) * float("nan"))
    out = tmp_path / "m.pt"
    out.write_bytes(b"old")
    before = snapshot(tmp_path)
    assert main(["train", "--data", str(data), "-o", str(out), *TINY]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "training diverged at step 1" in err[0] and "nan" in err[0], err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("index", range(8))
def test_shipped_checkpoints_load_checked_and_a_copy_without_its_json_loads_as_its_digest_says(index, tmp_path):
    """Each shipped .pt matches the digest it or its .json states; alone (no .json), one written with its digest
    loads quietly and one written before digests loads with one note."""
    from sctn.checkpoint import read_checkpoint

    pt, kind = shipped()[index]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        blob = read_checkpoint(pt, kind, kind)
    assert (DIGEST_KEY in blob["meta"]) == DIGEST_IN_PT[pt.name]
    alone = tmp_path / pt.name
    shutil.copy(pt, alone)
    if DIGEST_IN_PT[pt.name]:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            read_checkpoint(alone, kind, kind)
    else:
        with pytest.warns(UndigestedCheckpointWarning, match="no weights_sha256 digest"):
            read_checkpoint(alone, kind, kind)
    flip_weight_bytes(alone)
    with pytest.raises(UserError, match="damaged"):
        read_checkpoint(alone, kind, kind)
