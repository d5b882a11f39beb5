"""Qt widgets of the operator console; each owns one pane and is fed by the main window's refresh tick."""
