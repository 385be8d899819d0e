"""The operator's GUI (PySide6 + pyqtgraph): :class:`~rigctl.gui.run_panel.RunPanel` runs protocols.

Importing this package does not import Qt; ``rigctl.gui.run_panel`` and ``rigctl.gui.app`` do.
"""
