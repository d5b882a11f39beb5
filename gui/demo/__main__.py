"""``python -m gui.demo ...``: the demo hardware child process (see `gui.demo.hardware.hardware_main`)."""
import sys

from gui.demo.hardware import hardware_main

sys.exit(hardware_main(sys.argv[1:]))
