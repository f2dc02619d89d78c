"""SiamRPN (Li et al. 2018) on ATSLTD frames, trained from scratch here (`dvsot train --model siamrpn`).

model.py: the narrowed AlexNet trunk and the up-channel region proposal head, checkpoints; anchors.py: anchors,
box encoding and training targets; crops.py: template and search crops; train.py: training on segment pairs;
tracker.py: the `siamrpn` tracker (cosine window, scale and aspect penalty, box refined by the regression).
"""
