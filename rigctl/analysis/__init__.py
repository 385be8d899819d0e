"""Analyse runs as the paper does (Han, Ding, Wu & Yan, Chinese Physics B 31, 2022, Secs. 2-5).

One idea per module; functions work on arrays and on run objects, so scripts, the report and the
GUI reuse them. Definitions and sources: docs/analysis.md. Reading the record itself
(slips, the drive, camera frames streamed in chunks, Isum(t), I(x,t), P(x,t)) is
:mod:`rigctl.records`, shared with the workbench; the analysis does not import the workbench.

* :mod:`~rigctl.analysis.source` - open a run file or CSV, say what it lacks
* :mod:`~rigctl.analysis.passes` - the tangential passes of a run (TLRE repetitions, sweep forces)
* :mod:`~rigctl.analysis.stickslip` - initial/stable stage and the stick/slip cycle table (the
  slip detector of :mod:`rigctl.records.events`, the workbench's too)
* :mod:`~rigctl.analysis.friction` - mu_s,max, mu_s, mu_k with spread
* :mod:`~rigctl.analysis.stiffness` - K_I along the Ft-delta curve and K(i)
* :mod:`~rigctl.analysis.repeatability` - relative errors of repeated loadings (Sec. 2.2)
* :mod:`~rigctl.analysis.sweep` - force-sweep summary and where stick-slip fades (Sec. 4.1)
* :mod:`~rigctl.analysis.contact_stress` - P at chosen Ft, Im(i)
* :mod:`~rigctl.analysis.contact_spots` - contact spots by a weighted multi-scale filter (WSM)
* :mod:`~rigctl.analysis.contact_csi` - colour superposition of three frames (CSI), its proportions
* :mod:`~rigctl.analysis.surface_psd` - power spectral density of a height map (Fig. 4d)
* :mod:`~rigctl.analysis.contact_run`, :mod:`~rigctl.analysis.contact_report` - the contact
  analyses of one run and its report section
* :mod:`~rigctl.analysis.mechanics`, :mod:`~rigctl.analysis.pipeline` - everything for one run or
  a campaign; :mod:`~rigctl.analysis.report` - index.html + analysis.json
"""
