"""SiamMask (Wang et al. 2019) on ATSLTD frames, trained from scratch here (`dvsot train --model siammask`).

model.py: the narrowed trunk, depth-wise correlation and the score, box and mask branches, checkpoints;
masks.py: mask targets of a search crop and the box from a predicted mask; train.py: training on segment pairs
with the dataset files' instance masks; tracker.py: the `siammask` tracker.
"""
