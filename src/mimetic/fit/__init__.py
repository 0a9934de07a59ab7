"""Fitting the reference head to a target: face detection in renders, then landmark and surface fits."""
