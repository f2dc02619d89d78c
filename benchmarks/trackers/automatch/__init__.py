"""AutoMatch (Zhang et al. 2021, "Learn to Match") on ATSLTD frames, trained from scratch here
(`dvsot train --model automatch`): the paper's matching operators and a fixed combination of them, not its search.

operators.py: the matching operators; crops.py: the template's target mask; model.py: the network and checkpoints;
train.py: training (Ocean's, benchmarks/trackers/ocean/train.py); tracker.py: the `automatch` tracker.
"""
