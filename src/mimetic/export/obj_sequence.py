"""Write an animation as one OBJ file per frame, for tools that read mesh sequences.

Blender (the "Stop-motion-OBJ" add-on, or Mesh Sequence Cache after a conversion), Houdini's File
SOP with ``$F4`` and most point-cache converters read numbered files ``frame_0001.obj``,
``frame_0002.obj``, … . Each file is the rig's mesh exactly as ``mimetic.mesh.io.save_mesh``
writes it (vertices in rig order and rig units, parts as ``g`` groups, per-vertex colours, a
``# units:`` comment), with that frame's vertex positions in the frame of the mesh the rig was
made from (``Rig.to_source_frame``: a Z-up scan's frames are Z-up, and the rest pose lies exactly
on the input mesh); so ``load_mesh`` reads any frame back with the rig's vertex order.
Frames are numbered from 1, with at least four digits.

The faces, groups and colours are the same in every frame, so they are encoded once; each frame
formats only its positions (about 70 ms a frame for the 13k-vertex default head). For the channel curves
as CSV (``time_s`` plus one column per channel) use ``mimetic.animate.clipfiles.save_csv``.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mimetic.atomic import WriteError, atomic_write_bytes
from mimetic.engines.basis import Basis, evaluate_basis
from mimetic.errors import ActivationError
from mimetic.export.gltf import ExportError
from mimetic.mesh.model import Mesh
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

BATCH_FRAMES = 64
"""Frames evaluated together from a basis (bounds the (frames, n, 3) float64 temporary)."""


def frame_name(prefix: str, frame: int, n_frames: int) -> str:
    """``<prefix><frame>.obj`` with the frame number zero-padded to max(4, digits of n_frames)."""
    return f"{prefix}{frame:0{max(4, len(str(n_frames)))}d}.obj"


class _ObjFrames:
    """OBJ text of the rig's mesh with new positions: the header and faces encoded once."""

    def __init__(self, mesh: Mesh) -> None:
        from mimetic.mesh.io import encode_obj  # the format save_mesh writes, byte for byte

        whole = encode_obj(mesh, "obj sequence")
        no_faces = Mesh(mesh.vertices, np.zeros((0, 3), np.int64), {}, mesh.colors, mesh.units)
        head_and_vertices = encode_obj(no_faces, "obj sequence")
        assert whole.startswith(head_and_vertices)
        self.tail = whole[len(head_and_vertices) :]  # groups and faces
        lines = head_and_vertices.split(b"\n")
        first_vertex = next(i for i, line in enumerate(lines) if line.startswith(b"v "))
        self.header = b"\n".join(lines[:first_vertex]) + b"\n"
        self.n = mesh.n_vertices
        if mesh.colors is None:
            self.template = "v %r %r %r\n" * self.n
            self.colors = None
        else:
            self.template = "v %r %r %r %r %r %r\n" * self.n
            self.colors = mesh.colors.astype(np.float64)  # float32 values, printed exactly

    def encode(self, vertices: np.ndarray) -> bytes:
        """The OBJ file (bytes) for positions (n, 3) float64."""
        rows = vertices if self.colors is None else np.hstack([vertices, self.colors])
        text = self.template % tuple(rows.ravel().tolist())
        return self.header + text.encode("ascii") + self.tail


def export_obj_sequence(
    rig: Rig,
    clip: Clip,
    folder: str | os.PathLike[str],
    *,
    basis: Basis | None = None,
    engine: str = "wire",
    prefix: str = "frame_",
    progress: Callable[[int, int], None] | None = None,
) -> tuple[Path, ...]:
    """Write one OBJ per frame of ``clip``: ``folder/frame_0001.obj``, … (each file atomically).

    Parameters
    ----------
    rig : Rig
        Gives the faces, parts, colours and units; and the engine when no ``basis`` is given.
    clip : Clip
        Channel values (frames, c) at ``clip.fps``; channels the rig lacks are an error, channels
        the clip lacks take their default.
    folder : path-like
        Created if missing (its parent must exist). Files already there with other frame numbers
        are left alone (a warning says how many).
    basis : Basis, optional
        Evaluate frames with ``evaluate_basis`` (fast) instead of running the engine.
    engine : {"wire", "vector"}
        The engine that deforms each frame when no basis is given.
    prefix : str
        File name before the frame number.
    progress : callable(done, total), optional
        Called after each frame.

    Returns
    -------
    paths : tuple of Path
        The files written, in frame order. Vertices are in rig order and rig units, in the user's
        source frame (``Rig.to_source_frame``).

    Raises
    ------
    ActivationError
        Clip channels that the rig (or the basis) lacks.
    ExportError
        A basis whose vertex count differs from the rig's, or a prefix with a path separator.
    WriteError
        The folder cannot be created or written; files already written stay, none is half-written.
    """
    folder = Path(folder)
    if not isinstance(clip, Clip):
        raise ExportError(f"clip must be a mimetic.rig.activations.Clip; got {type(clip).__name__}")
    if not prefix or os.sep in prefix or (os.altsep and os.altsep in prefix):
        raise ExportError(f"prefix={prefix!r} must be a non-empty file name prefix without folders")
    channels = basis.channels if basis is not None else rig.channel_names
    unknown = [c for c in clip.channels if c not in rig.channel_names]
    if unknown:
        raise ActivationError(
            f"clip channels {unknown[:5]} are not channels of the rig; rename or drop them (clip.select(...))"
        )
    if basis is not None and basis.n_vertices != rig.n_vertices:
        raise ExportError(
            f"the basis has {basis.n_vertices} vertices but the rig has {rig.n_vertices}; "
            "bake it from this rig"
        )
    values = clip.select(channels, {c.name: c.default for c in rig.channels}).values  # (f, c)
    try:
        folder.mkdir(exist_ok=True)
    except FileNotFoundError:
        raise WriteError(
            f"cannot create {folder}: its parent folder does not exist. Create it first."
        ) from None
    except (PermissionError, FileExistsError) as error:
        raise WriteError(f"cannot create the folder {folder}: {error.strerror or error}") from None

    frames = _ObjFrames(rig.source_mesh())
    total = clip.n_frames
    names = [frame_name(prefix, f + 1, total) for f in range(total)]
    stale = [
        p
        for p in folder.glob(f"{prefix}*.obj")
        if p.name not in set(names) and p.stem[len(prefix) :].isdigit()
    ]
    if stale:
        log.warning(
            "%s: %d older frame files (e.g. %s) are not part of this sequence",
            folder,
            len(stale),
            stale[0].name,
        )

    if basis is None:
        from mimetic.engines import make_engine

        model = make_engine(rig, engine)

        def batches():
            for f in range(total):
                yield f, model.deform(values[f])[None]

    else:

        def batches():
            for f0 in range(0, total, BATCH_FRAMES):
                yield f0, evaluate_basis(basis, values[f0 : f0 + BATCH_FRAMES])

    paths = []
    for f0, batch in batches():
        for k, vertices in enumerate(batch):
            path = folder / names[f0 + k]
            atomic_write_bytes(path, frames.encode(rig.to_source_frame(vertices)))
            paths.append(path)
            if progress is not None:
                progress(len(paths), total)
    log.info("wrote %d OBJ frames to %s (%g fps)", total, folder, clip.fps)
    return tuple(paths)
