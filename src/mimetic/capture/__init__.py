"""Drivers from captured motion: fit channel activations to tracked vertex positions.

``solve_activations(basis, targets, channels=rig)`` fits, frame by frame, the activations of a
baked ``Basis`` that best reproduce target vertex positions (bounded least squares, correctives
by Gauss-Newton); ``prepare_solver`` keeps its per-basis precomputation for many clips.
"""

from mimetic.capture.solve import ActivationSolver, SolveResult, prepare_solver, solve_activations

__all__ = ["ActivationSolver", "SolveResult", "prepare_solver", "solve_activations"]
