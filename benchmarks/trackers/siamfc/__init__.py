"""A SiamFC-style tracker on ATSLTD frames, trained from scratch here (`dvsot train --model siamfc`).

model.py: the shared backbone, cross-correlation and checkpoints; crops.py: exemplar and search crops;
train.py: training on frame pairs of the training split; tracker.py: the `siamfc` tracker.
"""
