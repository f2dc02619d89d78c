"""Ocean (Zhang et al. 2020) on ATSLTD frames, trained from scratch here (`dvsot train --model ocean`).

boxes.py: the anchor-free geometry (locations, targets, decoding, IoU loss), shared with AutoMatch; model.py: the
narrowed network and checkpoints; crops.py: training pairs' crops and boxes; train.py: training on pairs of the
training split; tracker.py: the `ocean` tracker (and the anchor-free tracking AutoMatch shares).
"""
