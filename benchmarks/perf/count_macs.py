"""Print the paper's Table 3 counted, not copied: MACs of the published trackers' networks at their papers' sizes.

    python -m benchmarks.perf.count_macs [--layers] [--json]

Networks from benchmarks/trackers/reference_nets.py (untrained, counted on the meta device by
sctn.macs): per frame (search branch and head on the cached template, what a tracker runs each
frame), per initialisation (template branch) and one pass of both (what a profiler given both crops
counts). --layers adds, per network, the per-frame and template MACs of each layer block.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

import torch

from benchmarks.analysis.paper import SIAMESE_MAC_PER_FRAME
from benchmarks.trackers.reference_nets import GOTURN, AutoMatch, Ocean, SiameseNet, SiamMask, SiamRPN, count_siamese


def networks() -> list[tuple[str, SiameseNet, str]]:
    """(row name, network, paper row it is compared with) for each counted configuration, on the meta device."""
    with torch.device("meta"):  # shapes only: no weights drawn
        return [("SiamRPN 127/255", SiamRPN(255), "SiamRPN"), ("SiamRPN 127/271", SiamRPN(271), "SiamRPN"),
                ("SiamMask 127/255 (no refinement)", SiamMask(), "SiamMask"), ("GOTURN 227/227", GOTURN(), ""),
                ("Ocean 127/255 (head widths assumed)", Ocean(), ""),
                ("AutoMatch 128/256 (operators as recalled, head widths assumed)", AutoMatch(), "")]


def block(name: str, depth: int = 2) -> str:
    """A module name's block: its path under the root cut to `depth` parts; a correlation outside modules or in
    the root's own forward is "correlation"."""
    parts = name.split(".")[1:]
    return ".".join(parts[:depth]) if parts else "correlation"


def by_block(by_layer: dict, depth: int = 2) -> dict[str, float]:
    """Per-layer MACs summed per block (see block)."""
    out: dict[str, float] = defaultdict(float)
    for name, macs in by_layer.items():
        out[block(name, depth)] += macs
    return dict(out)


def rows() -> list[dict]:
    """One row per network: MACs per frame, per initialisation and of both branches, the paper's figure, and
    the per-frame and template MACs per block."""
    out = []
    for name, net, paper in networks():
        c = count_siamese(net)
        frame, init, both = (c[k]["mac_ops"] for k in ("per_frame", "init", "template_and_search"))
        ref = SIAMESE_MAC_PER_FRAME.get(paper)
        out.append({"network": name, "per_frame": frame, "init": init, "template_and_search": both,
                    "paper_per_frame": ref, "per_frame_vs_paper": None if ref is None else frame / ref - 1,
                    "both_vs_paper": None if ref is None else both / ref - 1,
                    "frame_blocks": by_block(c["per_frame"]["by_layer"]),
                    "init_blocks": by_block(c["init"]["by_layer"])})
    return out


def fmt(v: float | None, pct: bool = False) -> str:
    """A count as 4.82e9 (a fraction as +1.2%); '-' when absent."""
    if v is None:
        return "-"
    return f"{v:+.1%}" if pct else f"{v:.3e}".replace("e+0", "e").replace("e+", "e")


def table(data: list[dict], layers: bool = False) -> str:
    """The rows as a markdown table (and per-block tables with layers=True)."""
    lines = ["| network (template/search) | MACs per frame | paper (Table 3) | frame vs paper | init (template) "
             "| template + search | both vs paper |", "|---|---|---|---|---|---|---|"]
    for r in data:
        lines.append(f"| {r['network']} | {fmt(r['per_frame'])} | {fmt(r['paper_per_frame'])} | "
                     f"{fmt(r['per_frame_vs_paper'], True)} | {fmt(r['init'])} | {fmt(r['template_and_search'])} | "
                     f"{fmt(r['both_vs_paper'], True)} |")
    if layers:
        for r in data:
            lines += ["", f"{r['network']}:", "", "| block | per frame | template (init) |", "|---|---|---|"]
            for b in dict.fromkeys([*r["frame_blocks"], *r["init_blocks"]]):
                lines.append(f"| {b} | {fmt(r['frame_blocks'].get(b, 0.0))} | {fmt(r['init_blocks'].get(b, 0.0))} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Print the table (markdown, or JSON with --json)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layers", action="store_true", help="add the per-block MACs of each network")
    ap.add_argument("--json", action="store_true", help="print JSON instead of markdown")
    args = ap.parse_args(argv)
    data = rows()
    print(json.dumps(data, indent=1) if args.json else table(data, args.layers))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
