"""Which tier a parametrized case runs in.

The fast suite (``make test``) checks each family of long cases (engine parity under a set of
settings, a study's writers) at its first configuration; the others run in the slow tier
(``make test-slow``, which CI runs too), so a family is checked by CI in full and by a
developer's ``make test`` at one point. ``docs/development.md`` says which tier holds what."""

import pytest


def first_fast(values, ids):
    """``values`` as ``pytest.param``s named ``ids``: the first in the fast suite, the others
    marked ``slow``."""
    values, ids = list(values), list(ids)
    if len(values) != len(ids):
        raise ValueError(f"{len(values)} values but {len(ids)} ids")
    return [
        pytest.param(value, id=name, marks=() if i == 0 else pytest.mark.slow)
        for i, (value, name) in enumerate(zip(values, ids))
    ]
