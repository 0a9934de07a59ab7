"""Deformation engines: activations in, vertex positions out (wire, vector; bones and skinning)."""
