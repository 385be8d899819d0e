"""Reading a measured record: what the workbench compares and the analysis reports, read once.

Below both :mod:`rigctl.analysis` and :mod:`rigctl.workbench` (it imports neither; the import
contracts in ``pyproject.toml`` check it). One idea per module:

prepared runs
    :mod:`~rigctl.records.dataset` (runs checked, a campaign made ready), the drive simplified
    (:mod:`~rigctl.records.drive_profile`), the normal force's coupling to the tangential one
    (:mod:`~rigctl.records.fn_coupling`), probes over range (:mod:`~rigctl.records.probe_range`),
    what the record says about its rig (:mod:`~rigctl.records.rig_description`), scales no friction
    record has (:mod:`~rigctl.records.unit_checks`), long records read on windows
    (:mod:`~rigctl.records.long_records`).
slip events and features
    :mod:`~rigctl.records.events` (the one slip detector), :mod:`~rigctl.records.features` (per-event
    features), :mod:`~rigctl.records.feature_info` (each feature's unit, residual form, wording),
    :mod:`~rigctl.records.ringing` (post-slip ringing), :mod:`~rigctl.records.signals` (shared
    numerical helpers).
contact images
    :mod:`~rigctl.records.contact_frames` (frames streamed in chunks), :mod:`~rigctl.records.frame_inflate`
    (their fast inflate), :mod:`~rigctl.records.contact_intensity` (Isum(t), I(x, t), the contact
    region), :mod:`~rigctl.records.contact_profile` (P(x, t), P(k, t)),
    :mod:`~rigctl.records.image_features` (the image features the model is compared by);
    :mod:`~rigctl.records.progress` shows progress of long reads.
"""
