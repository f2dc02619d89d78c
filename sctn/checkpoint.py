"""SCTN checkpoints: weights + network config + how they were made; the shipped default checkpoint."""

from __future__ import annotations

import hashlib
import json
import os
import warnings
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path

import torch
from pydantic import ValidationError

from dvsot.core.bounds import file_kind_problem
from dvsot.core.errors import RunError, UserError, exception_line
from dvsot.runtime.outputs import replacing, run_outputs
from sctn.network import SCTN, NetworkConfig

CHECKPOINT_DIR = Path(__file__).resolve().parent / "checkpoints"
DIGEST_KEY = "weights_sha256"  # the metadata field (in the .pt and its .json) holding weights_digest of the weights
VERSIONS = (1,)  # the checkpoint layouts this code reads ("version" in the stored dict)


class LegacyLayoutWarning(UserWarning):
    """A checkpoint whose network is not the paper preset (biases, tail steps or other steps)."""


class TrainingRuleWarning(UserWarning):
    """A checkpoint trained with another recipe than `dvsot train`'s (sctn.training.snn.training_note)."""


def layout_note(cfg: NetworkConfig) -> str | None:
    """What makes a network config differ from the paper preset's layout, or None if it is the preset's."""
    ways = []
    if cfg.bias:
        ways.append("layers with biases (an empty input can fire)")
    if cfg.tail_steps:
        ways.append(f"{cfg.tail_steps} empty tail steps")
    if cfg.steps != 10 or cfg.step_us != 1000:
        ways.append(f"{cfg.steps} steps of {cfg.step_us} us")
    return ("not the paper preset: " + ", ".join(ways)) if ways else None


# The SCTN checkpoints shipped with the package, by name; each one's .json says how it was made.
# "dvsot21": the paper's row, trained on Table 1's four training scenes (the default);
# "varied": the same recipe on those four plus four scenes of blender_scenes/templates/dvsot21_varied.yaml.
SHIPPED = {"dvsot21": "sctn_dvsot21.pt", "varied": "sctn_dvsot21_varied.pt"}


def shipped_checkpoint_path(name: str = "dvsot21") -> Path:
    """The file of a shipped SCTN checkpoint by its name in SHIPPED; UserError naming the choices otherwise."""
    if name not in SHIPPED:
        raise UserError(f"{name!r}: no shipped SCTN checkpoint of that name (choose from {', '.join(SHIPPED)})")
    return CHECKPOINT_DIR / SHIPPED[name]


def default_checkpoint_path() -> Path:
    """The default shipped checkpoint: the paper's row, trained by `dvsot train` on the DVSOT21-style training split."""
    return shipped_checkpoint_path("dvsot21")


def metadata_path(path: str | os.PathLike) -> Path:
    """Where save_checkpoint writes a checkpoint's metadata: next to it, as .json."""
    return Path(path).with_suffix(".json")


def check_checkpoint_output(path: str | os.PathLike, flag: str = "checkpoint", inputs=()) -> Path:
    """`path` as a checkpoint to (re)write, with its .json beside it; UserError before any work if it cannot be."""
    from dvsot.runtime.outputs import output_file

    p = output_file(path, flag, inputs)
    meta = metadata_path(p)
    if meta == p:
        raise UserError(f"{p}: {flag} must not end in .json: the checkpoint's metadata is written to {meta.name}")
    output_file(meta, f"{flag} (its metadata file)", inputs)
    return p


class UndigestedCheckpointWarning(UserWarning):
    """A checkpoint written before weight digests: only its zip CRCs can be checked."""


def weights_digest(state: Mapping[str, torch.Tensor]) -> str:
    """SHA-256 (hex) of a state dict: every tensor's name, dtype, shape and bytes, in name order."""
    h = hashlib.sha256()
    for name in sorted(state):
        t = state[name].detach().cpu().contiguous()
        h.update(f"{name}\0{t.dtype}\0{tuple(t.shape)}\0".encode())
        h.update(t.view(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
    return h.hexdigest()


def non_finite_weights(state: Mapping[str, torch.Tensor]) -> list[tuple[str, int]]:
    """(name, count) of every floating-point tensor of a state dict holding NaN or infinite values."""
    bad = []
    for name, t in state.items():
        if torch.is_floating_point(t):
            n = int((~torch.isfinite(t)).sum())
            if n:
                bad.append((name, n))
    return bad


def _non_finite_text(bad: list[tuple[str, int]]) -> str:
    """'N non-finite values (NaN or inf) in a, b, ...' for non_finite_weights' list."""
    names = ", ".join(name for name, _ in bad[:3]) + (f" and {len(bad) - 3} more" if len(bad) > 3 else "")
    return f"{sum(n for _, n in bad)} non-finite values (NaN or inf) in {names}"


def save_checkpoint(path: str | os.PathLike, model: torch.nn.Module, meta: dict, kind: str = "sctn") -> Path:
    """Write weights, config and metadata, plus a .json of the metadata: both new or both old (one run's pair).

    Both files carry the same `run` id (the .pt in its metadata), so a reader can tell they belong together, and
    the weights' digest (weights_digest), which read_checkpoint checks. Non-finite weights are refused (RunError).
    `kind` names the model the file holds (sctn, sctn_ann, siamfc): its format is "<kind>-checkpoint", so a
    checkpoint given to another model is refused naming what it holds (read_checkpoint).
    """
    p = check_checkpoint_output(path)
    meta_path = metadata_path(p)
    state = {k: v.detach().to(torch.float32).clone() for k, v in model.state_dict().items()}
    bad = non_finite_weights(state)
    if bad:  # a diverged training: such weights score nothing, and -o keeps what it held
        raise RunError(f"{p}: not written: the weights hold {_non_finite_text(bad)}")
    with run_outputs() as run:  # renamed together when both are complete (dvsot.runtime.outputs)
        meta = {**meta, "run": run.run_id, DIGEST_KEY: weights_digest(state)}
        with replacing(p) as tmp, open(tmp, "wb") as f:  # a file object: a full disk is an OSError, not torch's
            torch.save({"format": f"{kind}-checkpoint", "version": 1, "config": model.cfg.model_dump(),
                        "state_dict": state, "meta": meta}, f)
        with replacing(meta_path) as tmp_json:
            tmp_json.write_text(json.dumps({"model": kind, "config": model.cfg.model_dump(), **meta}, indent=2,
                                           default=str))
    return p


def _zip_damage(p: Path) -> str | None:
    """The first member of a zip-format .pt whose CRC does not match its bytes (torch.load does not check), if any."""
    if not zipfile.is_zipfile(p):
        return None  # torch's legacy format: torch.load checks it
    try:
        with zipfile.ZipFile(p) as z:
            return z.testzip()
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, NotImplementedError):
        return None  # a damaged directory: torch.load refuses the file


def _digest_type_problem(value: object) -> str | None:
    """Why a stored digest is no SHA-256 text (an integer, a list, ...), or None if it is text."""
    if isinstance(value, str):
        return None
    return f"its {DIGEST_KEY} is {type(value).__name__} {str(value)[:40]}, expected 64 hexadecimal digits"


def _expected_digest(p: Path, meta: dict, label: str = "SCTN") -> str | None:
    """The weights' digest a checkpoint states: in its metadata, else in the .json of the same run beside it; a
    digest of another type than text is a UserError (it is no digest to skip, but a damaged one)."""
    if DIGEST_KEY in meta:
        problem = _digest_type_problem(meta[DIGEST_KEY])
        if problem:
            raise UserError(f"{p}: damaged {label} checkpoint: {problem}")
        return meta[DIGEST_KEY]
    from dvsot.runtime.inputs import read_text

    try:  # a checkpoint written before digests whose digest was derived later into its .json (shipped ones)
        text = read_text(metadata_path(p), "the checkpoint's metadata file", missing_ok=True)  # a FIFO: refused
        side = json.loads(text) if text is not None else None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        if isinstance(exc, UserError):
            raise
        return None
    if isinstance(side, dict) and side.get("run") == meta.get("run") and DIGEST_KEY in side:
        problem = _digest_type_problem(side[DIGEST_KEY])
        if problem:
            raise UserError(f"{metadata_path(p)}: damaged metadata of {p.name}: {problem}")
        return side[DIGEST_KEY]
    return None


def check_weights(p: Path, blob: dict, label: str) -> None:
    """UserError naming the file unless the stored weights are tensors, finite and match their stated digest; a
    checkpoint stating none (written before digests) passes with an UndigestedCheckpointWarning."""
    state = blob.get("state_dict")
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise UserError(f"{p}: not a usable {label} checkpoint (its state_dict is not a set of tensors)")
    meta = blob.get("meta") if isinstance(blob.get("meta"), dict) else {}
    expected = _expected_digest(p, meta, label)
    if expected is not None and weights_digest(state) != expected:
        raise UserError(f"{p}: damaged {label} checkpoint: its weights do not match their {DIGEST_KEY} digest")
    bad = non_finite_weights(state)
    if bad:
        raise UserError(f"{p}: not a usable {label} checkpoint: its weights hold {_non_finite_text(bad)}")
    if expected is None:
        warnings.warn(f"{p}: no {DIGEST_KEY} digest (written before digests): only its zip CRCs are checked",
                      UndigestedCheckpointWarning, stacklevel=3)


def read_checkpoint(path: str | os.PathLike, kind: str, label: str, article: str = "a") -> dict:
    """The stored dict of a `kind` checkpoint (format "<kind>-checkpoint") with intact, finite weights (its zip
    CRCs and weight digest checked: check_weights); UserError naming the file otherwise, and the model it holds
    when it is another dvsot model's checkpoint. `label` (after `article`) names the model in messages."""
    p = Path(path)
    kind_problem = file_kind_problem(p)  # before torch.load: a FIFO would block it, a directory is no checkpoint
    if kind_problem == "no such file":
        raise UserError(f"{p}: no such checkpoint")
    if kind_problem:
        raise UserError(f"{p}: {kind_problem}, not a checkpoint file")
    damaged = _zip_damage(p)
    if damaged:
        raise UserError(f"{p}: damaged {label} checkpoint: {damaged} does not match its zip CRC")
    try:
        blob = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several kinds for damaged files
        raise UserError(f"{p}: not a readable {label} checkpoint ({type(exc).__name__})") from None
    fmt = blob.get("format") if isinstance(blob, dict) else None
    if fmt != f"{kind}-checkpoint":
        held = fmt.removesuffix("-checkpoint") if isinstance(fmt, str) and fmt.endswith("-checkpoint") else None
        if held:
            raise UserError(
                f"{p}: holds a {held} model, not {article} {label} one (a checkpoint of the {held} tracker)"
            )
        raise UserError(f"{p}: not {article} {label} checkpoint")
    version = blob.get("version")
    if isinstance(version, bool) or version not in VERSIONS:
        raise UserError(f"{p}: {label} checkpoint version {str(version)[:40]} is not one this dvsot reads "
                        f"({', '.join(map(str, VERSIONS))})")
    check_weights(p, blob, label)
    return blob


def stored_checkpoint(path: str | os.PathLike | None, default: Path, kind: str, label: str,
                      article: str = "a") -> tuple[Path, dict]:
    """The file and stored dict of a `kind` checkpoint (`default` if path is None); UserError naming the file if it
    is missing or not such a checkpoint (read_checkpoint)."""
    p = Path(path) if path is not None else default
    if path is None and not p.is_file():
        how = "`dvsot train`" if kind == "sctn" else f"`dvsot train --model {kind}`"
        raise UserError(f"{p}: no such checkpoint (train one with {how})")
    return p, read_checkpoint(p, kind, label, article=article)


def load_model(path: str | os.PathLike | None, default: Path, kind: str, label: str,
               build: Callable[[dict], torch.nn.Module], article: str = "a") -> tuple[torch.nn.Module, dict]:
    """The network and metadata of a `kind` checkpoint (`default` if path is None): `build(blob)` makes the network
    from the stored dict, then its weights are loaded; UserError naming the file if it is missing or unusable."""
    p, blob = stored_checkpoint(path, default, kind, label, article)
    try:
        model = build(blob)
        model.load_state_dict(blob["state_dict"])
    except Exception as exc:  # a config or tensors that do not fit the network
        raise UserError(f"{p}: not a usable {label} checkpoint ({exception_line(exc, 200)})") from None
    model.eval()
    return model, blob.get("meta", {})


def load_checkpoint(path: str | os.PathLike | None = None) -> tuple[SCTN, dict]:
    """The model and metadata of a checkpoint (the shipped default if path is None); UserError if it is missing or
    not an SCTN checkpoint (a config or tensors that do not fit raise as they are: dvsot bench words them)."""
    p, blob = stored_checkpoint(path, default_checkpoint_path(), "sctn", "SCTN", article="an")
    config = dict(blob["config"])
    if "bias" not in config:  # written before the layers' bias became a setting: biased if it has bias tensors
        config["bias"] = any(k.endswith(".bias") for k in blob["state_dict"])
    try:
        cfg = NetworkConfig(**config)
    except ValidationError as exc:
        err = exc.errors()[0]
        field = ".".join(map(str, err["loc"])) or "config"
        raise UserError(f"{p}: not a usable SCTN checkpoint: config field '{field}' is {str(err.get('input'))[:40]} "
                        f"({err['msg'][:1].lower()}{err['msg'][1:]})") from None
    note = layout_note(cfg)
    if note:
        warnings.warn(f"{p}: {note}", LegacyLayoutWarning, stacklevel=2)
    from sctn.training.snn import training_note  # the training's settings live there

    rule = training_note(blob.get("meta", {}).get("train_config"))
    if rule:
        warnings.warn(f"{p}: {rule}", TrainingRuleWarning, stacklevel=2)
    model = SCTN(cfg)
    model.load_state_dict(blob["state_dict"])
    problem = time_constant_problem(model)
    if problem:
        raise UserError(f"{p}: not a usable SCTN checkpoint: {problem}")
    model.eval()
    return model, blob.get("meta", {})


def time_constant_problem(model: SCTN) -> str | None:
    """Why a network's learned C-LIF time constants (ms) give no finite kernel, or None.

    The kernel's decays d = exp(-1/a) and its norm V0 are computed in float32 (tracking) and float64 (NIR export):
    a finite but huge time constant makes d_m and d_s equal, V0 infinite and the exported constants NaN."""
    from sctn.neurons import kernel_norm

    with torch.no_grad():
        for i, neuron in enumerate(model.neurons):
            a_m, a_s = (t.detach() for t in neuron.time_constants())
            for dtype in (torch.float32, torch.float64):
                am, as_ = a_m.to(dtype), a_s.to(dtype)
                d_m, d_s = torch.exp(-1.0 / am), torch.exp(-1.0 / as_)
                v0 = kernel_norm(d_m, d_s, am, as_)
                bad = ~(torch.isfinite(am) & torch.isfinite(as_) & torch.isfinite(v0) & (v0 > 0) & (d_m > d_s))
                if bool(bad.any()):
                    c = int(torch.nonzero(bad)[0])
                    return (f"C-LIF layer {i} channel {c} has time constants alpha_m {float(a_m[c]):.6g} ms and "
                            f"alpha_s {float(a_s[c]):.6g} ms, whose PSP kernel is not finite in {str(dtype)[6:]} "
                            "(its decays per step are equal)")
    return None
