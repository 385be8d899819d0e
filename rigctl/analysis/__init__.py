"""Analyse runs as the paper does (Han, Ding, Wu & Yan, Chinese Physics B 31, 2022, Secs. 2-5).

One idea per module; functions work on arrays and on run objects, so scripts, the report, the GUI
and the workbench reuse them. Definitions and sources: docs/analysis.md.

* :mod:`~rigctl.analysis.source` - open a run file or CSV, say what it lacks
* :mod:`~rigctl.analysis.passes` - the tangential passes of a run (TLRE repetitions, sweep forces)
* :mod:`~rigctl.analysis.stickslip` - initial/stable stage and the stick/slip cycle table (the
  workbench's slip detector)
* :mod:`~rigctl.analysis.friction` - mu_s,max, mu_s, mu_k with spread
* :mod:`~rigctl.analysis.stiffness` - K_I along the Ft-delta curve and K(i)
* :mod:`~rigctl.analysis.repeatability` - relative errors of repeated loadings (Sec. 2.2)
* :mod:`~rigctl.analysis.sweep` - force-sweep summary and where stick-slip fades (Sec. 4.1)
* :mod:`~rigctl.records.contact_frames` - camera frames streamed in chunks (bounded memory)
* :mod:`~rigctl.records.contact_intensity` - Isum(t) (Eq. 1), I(x,t), the contact region
* :mod:`~rigctl.analysis.contact_stress` - P(x,t), P in the model's 10 parts, P at chosen Ft, Im(i)
* :mod:`~rigctl.analysis.contact_spots` - contact spots by a weighted multi-scale filter (WSM)
* :mod:`~rigctl.analysis.contact_csi` - colour superposition of three frames (CSI), its proportions
* :mod:`~rigctl.analysis.surface_psd` - power spectral density of a height map (Fig. 4d)
* :mod:`~rigctl.analysis.contact_run`, :mod:`~rigctl.analysis.contact_report` - the contact
  analyses of one run and its report section
* :mod:`~rigctl.analysis.mechanics`, :mod:`~rigctl.analysis.pipeline` - everything for one run or
  a campaign; :mod:`~rigctl.analysis.report` - index.html + analysis.json
"""
