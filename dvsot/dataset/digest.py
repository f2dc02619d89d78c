"""The root-attribute digest of a dataset file: SHA-256 of the other root attributes' canonical JSON, so that an
attribute changed after writing is found on open."""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

DIGEST_ATTR = "attrs_sha256"  # root attribute: SHA-256 of the other root attributes' canonical JSON


def _canonical(value: Any) -> Any:
    """A JSON-serialisable form of an attribute value that numpy or h5py handed back."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return str(value)


def attrs_digest(attrs: dict[str, Any]) -> str:
    """SHA-256 (hex) of the canonical JSON (sorted keys, no spaces) of decoded root attributes, the digest itself left
    out."""
    body = {k: v for k, v in attrs.items() if k != DIGEST_ATTR}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=_canonical)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def digest_problem(attrs: dict[str, Any]) -> str | None:
    """What is wrong with the root attributes' digest, or None (also when there is none: files before it)."""
    stored = attrs.get(DIGEST_ATTR)
    if stored is None:
        return None
    if stored != attrs_digest(attrs):
        return (f"the root attributes do not match their SHA-256 in root attribute '{DIGEST_ATTR}' "
                f"(an attribute was changed or corrupted after the file was written)")
    return None
