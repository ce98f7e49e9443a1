"""Reproductions of the paper's experiments (issue 13): Table 1 with the paper's own
method as written, Loop & Zhang rectification and SfM+MVS as baselines; the bas-relief
simulation of sec. 5.1; the stereo stage on Middlebury's Motorcycle pair."""
