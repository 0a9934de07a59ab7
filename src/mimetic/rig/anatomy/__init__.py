"""The rig's anatomy: what a face has besides muscles, wires and bones, as data the engines read.

* ``creases``: lines of skin that sink when a muscle contracts (forehead lines, glabella lines,
  crow's feet, the nasolabial fold), each a vertex set with its displacement at full depth;
* ``skull``: the bony surface under the forehead that the skin slides over and never enters;
* ``lip_contact``: the (upper, lower) lip vertex pairs that touch at rest, so lips meet but never
  cross;
* ``accessories``: small separate pieces riding the skin (eyelashes, brow cards, tear lines), each
  vertex riveted to the skin under its root;
* ``lids``: where each eye's upper lid meets its lower lid (the margins' contact, kept by the
  engines so lids close but never cross), and the closing weights that bring them together;
* ``actions``: tissue actions, the displacement fields of muscles that wires and vector muscles
  cannot make (the frontalis lifting the whole forehead, the cheek raised toward the eye, the lips
  rolled in or pushed out, the cheeks puffed, the tongue put out), each linear in one channel;
* ``tissue_normals``: the directions creases sink and tissue actions bulge along: the skin's
  normals with the lips closed, smoothed (not stored: derived from the mesh when the rig is);
* ``thickness``: the soft-tissue thickness under every skin vertex (thin on the lids and over the
  nose, thick on the cheeks), which the physically based engines lay their tissue layers on.

Each element is one pure function of the rig's mesh, landmarks, regions and skin weights
(``derive_anatomy`` runs them all), called by both ``build_rig`` and the rig transfer, so a fitted
head gets its anatomy by the same rules as the reference. The functions see the mesh with its
unwelded seams merged (``mimetic.mesh.weld``) and hand every copy of a merged vertex the same
data, so nothing that uses the topology (normals, separate pieces) tears a seam. Lengths are
fractions of the head height (``Rig.scale``), named ``_rel``.
"""

from mimetic.rig.anatomy.accessories import Accessories, find_accessories
from mimetic.rig.anatomy.actions import Action, find_actions
from mimetic.rig.anatomy.creases import Crease, find_creases
from mimetic.rig.anatomy.derive import Anatomy, derive_anatomy, tissue_normals
from mimetic.rig.anatomy.lids import LidContact, closing_weights, find_lid_contacts
from mimetic.rig.anatomy.lips import lip_contact
from mimetic.rig.anatomy.skull import Skull, forehead_skull
from mimetic.rig.anatomy.tissue import tissue_thickness

__all__ = [
    "Accessories",
    "Action",
    "Anatomy",
    "Crease",
    "LidContact",
    "Skull",
    "closing_weights",
    "derive_anatomy",
    "find_accessories",
    "find_actions",
    "find_creases",
    "find_lid_contacts",
    "forehead_skull",
    "lip_contact",
    "tissue_normals",
    "tissue_thickness",
]
