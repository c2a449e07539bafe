"""The generated bad-input tests' shared pieces: one bad input (:class:`Case`) and a list that
collects them as pytest parameters (:class:`Cases`)."""

from __future__ import annotations

import re
from dataclasses import dataclass

import pytest


@dataclass(frozen=True)
class Case:
    """One bad input: ``build(context)`` must raise ``error`` with ``field`` in its message."""

    build: object
    error: type
    field: str

    def check(self, context) -> None:
        """``build(context)`` raises exactly ``error``, its message naming ``field``."""
        with pytest.raises(Exception) as caught:
            self.build(context)  # type: ignore[operator]
        assert type(caught.value) is self.error, f"{type(caught.value).__name__}: {caught.value}"
        assert self.field in str(caught.value), str(caught.value)


class Cases(list):
    """The cases of a test module, as pytest parameters with readable ids."""

    def add(self, surface: str, value, build, field: str, error: type = ValueError) -> None:
        # (a repr holding an address, "<object object at 0x…>", differs between xdist's workers)
        shown = re.sub(r" at 0x[0-9a-f]+", "", " ".join(repr(value).split()))[:50]
        self.append(pytest.param(Case(build, error, field), id=f"{surface}-{shown}"))
