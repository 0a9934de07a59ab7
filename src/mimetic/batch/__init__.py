"""Many heads and clips at once, on a Dask cluster (local or multi-node) or a process pool.

Each job is what its single-file command does, once per input, with the same outputs::

    from mimetic.batch import rig_many

    manifest = rig_many("scans/*.obj", "rigs/", workers=8, landmarks="{dir}/{stem}.json")
    for row in manifest.failed:
        print(row.item, row.error)

``rig_many``, ``animate_many``, ``render_many``, ``speak_many`` and ``capture_many`` (and the
general ``run_batch``) each return a ``Manifest`` of ``Row``s and write it into the output folder
(``batch-KIND.json`` and ``.csv``). Items that fail report a one-line error and the others still
finish; finished items are skipped when the batch runs again (``resume``). The command line is
``mimetic batch rig|animate|render|speak|capture``.

Modules: ``items`` (inputs, globs and manifest files → ``Item``), ``jobs`` (what runs on a worker),
``manifest`` (results and completion records), ``run`` (clusters and pools). Dask is the optional
extra ``[batch]``; without it a ``ProcessPoolExecutor`` runs the items.
"""

from mimetic.batch.items import BatchError, Item, collect_items
from mimetic.batch.manifest import Manifest, Row
from mimetic.batch.run import animate_many, capture_many, render_many, rig_many, run_batch, speak_many

__all__ = [
    "BatchError",
    "Item",
    "Manifest",
    "Row",
    "animate_many",
    "capture_many",
    "collect_items",
    "render_many",
    "rig_many",
    "run_batch",
    "speak_many",
]
