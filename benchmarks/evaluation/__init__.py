"""Running trackers: the protocol with re-initialisation (protocol), one-pass evaluation (ope), trackers x files
(runner), A / R / ARscore (metrics), challenge attributes (attributes) and the networks a run loads up front
(models)."""
