"""Qt widgets of the operator console; each owns one pane and is fed by the main window's refresh tick."""

# tooltip / message on controls a viewer connection may not use (the gateway refuses them: docs/gateway.md roles)
VIEWER_ONLY = "this console connected with the viewer secret (watch only): the operator secret is needed for this"
