"""Running trackers: the protocol with re-initialisation (protocol), one-pass evaluation (ope), trackers x files
(runner), A / R / ARscore (metrics), ATSLTD frames (atsltd) and the networks a run loads up front (models)."""
