"""What the exact-model tests share: counting how often the option models are computed."""

import himit_torch.exact.option_models as om


def counting_option_models(monkeypatch) -> list[int]:
    """Wrap the option models' computation so each call appends how many variants it computed;
    returns that list (empty: every request was answered from a memo or the cache)."""
    calls: list[int] = []
    compute = om._option_models

    def counted(world, options, variants):
        calls.append(len(variants))
        return compute(world, options, variants)

    monkeypatch.setattr(om, "_option_models", counted)
    return calls
