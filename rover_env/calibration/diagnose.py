"""placeholder"""

from typing import Any


def add_cli(sub: Any) -> None:
    pass
