"""A benchmark run (`dvsot bench`) from end to end: every input checked, the trackers run, the tables written (plan).

Above analysis: it runs evaluation's protocol and writes analysis's tables."""
