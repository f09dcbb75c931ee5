"""``python -m ipromp_pin.cli``: the ``ipromp-pin`` console script."""

from . import console_main

console_main()
