"""Multiply-accumulate counter over a network as run: torch's dispatch sees every matrix product and convolution.

Counted (MACs, one multiply and its add; bias additions, activations, pooling, normalisation and
interpolation are not MACs and are left out, as in the paper's eq. 13):
- convolution, any dimension, stride, padding, dilation, groups: output positions x kernel taps x
  (input channels / groups) x output channels x batch; padded taps count (the dense kernel runs them);
- transposed convolution (deconvolution): input positions x kernel taps x input channels x
  (output channels / groups) x batch, the products it forms (equal to the convolution it transposes);
- functional cross-correlation (F.conv2d with a data-dependent kernel, grouped "up-channel" or
  depth-wise): the same convolution formula, whatever makes the call;
- mm, addmm, bmm, baddbmm, addbmm, mv, addmv, dot, vdot (linear layers, matmul, einsum, attention
  products reach these): m x k x n per product;
- _trilinear (nn.Bilinear): batch x out x in1 x in2.

Attribution: each operation goes to the innermost module running it (module forward hooks), named
"Root.path" (root's class name and the module's path under it; "functional" when no module runs);
a parent module's own operations (a correlation in a Siamese net's forward) stay with the parent.
Shapes only: inputs and weights on the "meta" device count without computing anything.
"""

from __future__ import annotations

from collections import defaultdict
from math import prod

import torch
from torch import nn
from torch.utils._python_dispatch import TorchDispatchMode

aten = torch.ops.aten


def _conv(args: tuple, out: torch.Tensor) -> tuple[str, int]:
    # the weight's shape carries the grouping: (C_out, C_in / g, *k), or (C_in, C_out / g, *k) when transposed
    x, w, transposed = args[0], args[1], bool(args[6])
    if transposed:  # every input element meets every tap of its group's kernels
        return "conv_transpose", x.shape[0] * prod(x.shape[2:]) * prod(w.shape)
    return "conv", out.shape[0] * prod(out.shape[2:]) * prod(w.shape)


def _mm(a: torch.Tensor, b: torch.Tensor) -> int:
    return a.shape[0] * a.shape[1] * b.shape[1]


def _bmm(a: torch.Tensor, b: torch.Tensor) -> int:
    return a.shape[0] * a.shape[1] * a.shape[2] * b.shape[2]


def _trilinear(args: tuple, out: torch.Tensor) -> int:
    # F.bilinear calls it as (x1 (B, I), W (O, I, J), x2 (B, J)): one MAC per (b, o, i, j)
    return out.numel() * args[0].shape[-1] * args[2].shape[-1]


FORMULAS = {
    aten.convolution.default: _conv,
    aten._convolution.default: _conv,
    aten.mm.default: lambda a, o: ("matmul", _mm(a[0], a[1])),
    aten.addmm.default: lambda a, o: ("matmul", _mm(a[1], a[2])),
    aten.bmm.default: lambda a, o: ("matmul", _bmm(a[0], a[1])),
    aten.baddbmm.default: lambda a, o: ("matmul", _bmm(a[1], a[2])),
    aten.addbmm.default: lambda a, o: ("matmul", _bmm(a[1], a[2])),
    aten.mv.default: lambda a, o: ("matmul", a[0].shape[0] * a[0].shape[1]),
    aten.addmv.default: lambda a, o: ("matmul", a[1].shape[0] * a[1].shape[1]),
    aten.dot.default: lambda a, o: ("matmul", a[0].shape[0]),
    aten.vdot.default: lambda a, o: ("matmul", a[0].shape[0]),
}


class MacCounter(TorchDispatchMode):
    """Context manager counting MACs per module and per kind of operation while a network runs."""

    def __init__(self, root: nn.Module | None = None) -> None:
        super().__init__()
        self.by_module: dict[str, int] = defaultdict(int)
        self.by_kind: dict[str, int] = defaultdict(int)
        self._names: dict[int, str] = {}
        self._owners: dict[str, int] = {}
        self._stack: list[str] = []
        self._handles: list = []
        if root is not None:
            self._name_tree(root)

    def _name_tree(self, root: nn.Module) -> None:
        base = type(root).__name__
        roots = [name for name in self._owners if "." not in name]
        taken = sum(1 for name in roots if name == base or name.startswith(base + "#"))
        if taken:  # another root of the same class: keep the two apart
            base = f"{base}#{taken + 1}"
        for path, mod in root.named_modules():
            if id(mod) not in self._names:
                name = f"{base}.{path}" if path else base
                self._names[id(mod)] = name
                self._owners[name] = id(mod)

    def _pre(self, module: nn.Module, args) -> None:
        if id(module) not in self._names:
            self._name_tree(module)
        self._stack.append(self._names[id(module)])

    def _post(self, module: nn.Module, args, out) -> None:
        if self._stack:
            self._stack.pop()

    def __enter__(self):
        from torch.nn.modules.module import register_module_forward_hook, register_module_forward_pre_hook

        self._handles = [register_module_forward_pre_hook(self._pre), register_module_forward_hook(self._post)]
        return super().__enter__()

    def __exit__(self, *exc):
        for h in self._handles:
            h.remove()
        self._handles, self._stack = [], []
        return super().__exit__(*exc)

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        out = func(*args, **(kwargs or {}))
        if func in FORMULAS:
            kind, macs = FORMULAS[func](args, out)
        elif func is aten._trilinear.default:
            kind, macs = "bilinear", _trilinear(args, out)
        else:
            return out
        self.by_module[self._stack[-1] if self._stack else "functional"] += int(macs)
        self.by_kind[kind] += int(macs)
        return out

    @property
    def total(self) -> int:
        """All MACs counted so far."""
        return sum(self.by_kind.values())


def count_macs(fn, *inputs: torch.Tensor, root: nn.Module | None = None) -> dict:
    """MACs of one call fn(*inputs) (a module, or any function of modules; no gradients):
    {"mac_ops": total, "by_layer": {module name: MACs}, "by_kind": {conv|conv_transpose|matmul|bilinear: MACs}}.
    Modules under `root` (fn itself when it is a module) are named from it; others from the first one called."""
    counter = MacCounter(root if root is not None else fn if isinstance(fn, nn.Module) else None)
    with counter, torch.no_grad():
        fn(*inputs)
    by_layer = {name: float(m) for name, m in counter.by_module.items() if m}
    return {"mac_ops": float(counter.total), "by_layer": by_layer,
            "by_kind": {k: float(m) for k, m in counter.by_kind.items() if m}}
