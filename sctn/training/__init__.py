"""Training SCTN: the loop every trainer shares (loop) and SCTN trained directly as an SNN (snn)."""
