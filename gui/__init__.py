"""Operator console (PySide6 + pyqtgraph + moderngl). Optional extra: ``pip install 'courtside[console]'``."""
