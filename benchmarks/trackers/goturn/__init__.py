"""GOTURN (Held et al. 2016) on ATSLTD frames, trained from scratch here (`dvsot train --model goturn`).

model.py: the narrowed CaffeNet trunk shared by both crops and the fully connected regressor, checkpoints;
crops.py: the context crops and the box parametrisation; train.py: training on consecutive segment pairs with
GOTURN's motion augmentation; tracker.py: the `goturn` tracker.
"""
