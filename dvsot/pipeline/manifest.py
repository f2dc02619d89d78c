"""The manifest of a many-scene run: one record per scene (variant, seed, file, drawn values, status, attempts).

It is rewritten whole and atomically (temp file + rename) after every result, so a stopped run leaves one
that says what was done.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from dvsot.pipeline.scene_task import SceneTask
from dvsot.runtime.dask_tasks import Failure
from dvsot.runtime.outputs import replacing


class Manifest:
    """The run's manifest (path None: kept in memory only, for one scene rendered here)."""

    def __init__(self, path: Path | None, tasks: list[SceneTask]) -> None:
        self.path = path
        self.timing: dict = {}  # seconds: cluster start, workers' warm-up, submit -> last result
        self.records = [{"name": t.name, **t.record, "file": str(Path(t.output)), "status": "pending",
                         "attempts": [], "error": None} for t in tasks]
        self.summaries: list[dict | None] = [None] * len(tasks)  # each rendered scene's whole summary (not written)

    def write(self) -> None:
        """Replace the manifest file with the records as they are now."""
        if self.path is None:
            return
        with replacing(self.path) as tmp:
            tmp.write_text(json.dumps({"format": "dvsot-manifest", "version": 1, "timing": self.timing,
                                       "scenes": self.records}, indent=1)
                           + "\n")

    def record(self, i: int, outcome: Any, final: bool) -> dict:
        """Record an attempt of scene i (render_task's summary, its {"error"} or a Failure), write; the record."""
        rec = self.records[i]
        failure = scene_failure(outcome)
        if failure is None:
            rec["attempts"].append({"worker": outcome.get("worker"), "error": None, "wall_s": outcome.get("wall_s"),
                                    "task_s": outcome.get("task_s"), "cpu_s": outcome.get("cpu_s"),
                                    "render_threads": outcome.get("render_threads"), "cpus": outcome.get("cpus")})
            rec.update(status="done", error=None, events=outcome.get("events"), frames=outcome.get("frames"),
                       warnings=outcome.get("warnings") or [])
            self.summaries[i] = outcome
        else:
            rec["attempts"].append({"worker": failure.worker, "error": failure.error})
            rec.update(status="failed" if final else "retrying", error=failure.error)
        self.write()
        return rec

    def failed(self) -> bool:
        """Whether any scene finally failed."""
        return any(r["status"] == "failed" for r in self.records)


def scene_failure(outcome: Any) -> Failure | None:
    """render_task's {"error": ...} (or a Failure from dvsot.runtime.dask_tasks) as a Failure; None for a summary."""
    if isinstance(outcome, Failure):
        return outcome
    if isinstance(outcome, dict) and "error" in outcome:
        return Failure(outcome["error"], outcome.get("worker"))
    return None if isinstance(outcome, dict) else Failure(f"unexpected task result {type(outcome).__name__}")


def summary_line(manifest: Manifest) -> str:
    """One line: how many scenes were rendered, skipped (resumed) and failed."""
    recs = manifest.records
    resumed = sum(1 for r in recs if r.get("resumed"))
    done = sum(1 for r in recs if r["status"] == "done") - resumed
    failed = [r["name"] for r in recs if r["status"] == "failed"]
    text = f"{done} rendered, {resumed} already done, {len(failed)} failed"
    return text + (f" ({', '.join(failed[:10])}{' ...' if len(failed) > 10 else ''})" if failed else "") + \
        f"; manifest {manifest.path}"
