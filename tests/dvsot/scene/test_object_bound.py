"""The bound on objects a scene's per-event labels can name holds for checks and dry runs as for generate."""

from pathlib import Path

from dvsot.cli import main
from dvsot.events.labels import MAX_OBJECTS

TEMPLATE = """name: crowd
seed: 3
duration_s: 0.1
sensor: {{width: 80, height: 60}}
camera:
  keyframes: [{{t: 0, location: [0, -10, 0], look_at: [0, 0, 0]}}]
target:
  shape: cube
  trajectory: {{keyframes: [{{t: 0, location: [{{uniform: [-1, 1]}}, 0, 0]}}]}}
objects:
  - count: {count}
    each:
      role: distractor
      shape: sphere
      trajectory: {{keyframes: [{{t: 0, location: [2, 0, 0]}}]}}
"""


def test_dry_run_refuses_more_objects_than_labels_hold(tmp_path: Path, capsys) -> None:
    path = tmp_path / "crowd.yaml"
    path.write_text(TEMPLATE.format(count=MAX_OBJECTS + 1))
    assert main(["generate", str(path), "--variants", "1", "--dry-run", "--out-dir", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "field 'objects'" in err[0] and f"at most {MAX_OBJECTS}" in err[0]
