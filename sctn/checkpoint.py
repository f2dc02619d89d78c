"""SCTN checkpoints: weights + network config + how they were made; the shipped default checkpoint."""

from __future__ import annotations

import json
import os
from pathlib import Path

import torch

from dvsot.errors import UserError
from sctn.network import SCTN, NetworkConfig

CHECKPOINT_DIR = Path(__file__).resolve().parent / "checkpoints"


def default_checkpoint_path() -> Path:
    """The checkpoint shipped with the package (trained by `dvsot train` on the DVSOT21-style training split)."""
    return CHECKPOINT_DIR / "sctn_dvsot21.pt"


def save_checkpoint(path: str | os.PathLike, model: SCTN, meta: dict) -> Path:
    """Write weights, config and metadata atomically (temp file, then rename), plus a .json of the metadata."""
    p = Path(path)
    if not p.parent.is_dir():
        raise UserError(f"{p}: output directory {p.parent} does not exist")
    state = {k: v.detach().to(torch.float32).clone() for k, v in model.state_dict().items()}
    tmp = p.with_name(f".{p.name}.tmp-{os.getpid()}")
    torch.save({"format": "sctn-checkpoint", "version": 1, "config": model.cfg.model_dump(), "state_dict": state,
                "meta": meta}, tmp)
    os.replace(tmp, p)
    meta_path = p.with_suffix(".json")
    tmp_json = meta_path.with_name(f".{meta_path.name}.tmp")
    tmp_json.write_text(json.dumps({"config": model.cfg.model_dump(), **meta}, indent=2, default=str))
    os.replace(tmp_json, meta_path)
    return p


def load_checkpoint(path: str | os.PathLike | None = None) -> tuple[SCTN, dict]:
    """The model and metadata of a checkpoint (the shipped default if path is None); UserError if unusable."""
    p = Path(path) if path is not None else default_checkpoint_path()
    if not p.is_file():
        raise UserError(f"{p}: no such checkpoint" + (" (train one with `dvsot train`)" if path is None else ""))
    try:
        blob = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several kinds for damaged files
        raise UserError(f"{p}: not a readable SCTN checkpoint ({type(exc).__name__})") from None
    if not isinstance(blob, dict) or blob.get("format") != "sctn-checkpoint":
        raise UserError(f"{p}: not an SCTN checkpoint")
    model = SCTN(NetworkConfig(**blob["config"]))
    model.load_state_dict(blob["state_dict"])
    model.eval()
    return model, blob.get("meta", {})
