"""SCTN: the spiking convolutional tracking network (C-LIF neurons, STCA-style training, tracking, energy)."""
