"""Lip sync: text, phoneme timings or audio → timed phones → visemes → coarticulated activations.

The stage produces a ``mimetic.rig.activations.Clip`` (frames × channels), so everything that takes
activations (engines, exporters, the video renderer) plays speech. Modules, in pipeline order:

* ``phones``: the timed-phone data (``Phone``, ``PhoneTimings``) every other module passes along;
* ``phonemes``: English text → ARPAbet (CMU dictionary, letter-to-sound fallback for unknown words
  and numbers);
* ``nso``: Northern Sotho (Sesotho sa Leboa) letters → phones and their durations;
* ``timings``: phone timings from Praat / Montreal Forced Aligner TextGrids, CSV, JSON and
  pocketsphinx alignment JSON, or naive timing from text and a speaking rate;
* ``align``: audio + transcript → phone timings offline (pocketsphinx, extra ``[speech]``), and
  synthesized audio for text through the ``espeak-ng`` program when installed;
* ``visemes``: phone → weighted blend of visemes plus channel offsets → channel targets (maps are
  data, per language);
* ``coarticulation``: Cohen–Massaro dominance blending of the targets in activation space → a Clip.
"""
