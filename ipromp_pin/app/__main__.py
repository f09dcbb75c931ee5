"""``python -m ipromp_pin.app``: the ``ipromp-pin`` console script."""

from . import console_main

console_main()
