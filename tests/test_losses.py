"""Loss terms of Table 2 against hand-computed values, and their numerical safety."""

import math

import pytest
import torch

from feeder.learn import losses


def t(rows):
    return torch.tensor(rows, dtype=torch.float64)


def test_cdf_pmf_roundtrip():
    p = t([[0.1, 0.2, 0.7], [1.0, 0.0, 0.0]])
    f = losses.cdf_from_pmf(p)
    assert torch.allclose(f, t([[0.1, 0.3, 1.0], [1.0, 1.0, 1.0]]))
    assert torch.allclose(losses.pmf_from_cdf(f), p)


def test_mse_hand_values():
    # row 1: ((0-1)^2 + 0) / 2 = 0.5; row 2: (0.25 + 0.25) / 2 = 0.25 -> mean 0.375
    assert losses.mse(t([[0, 1], [0.5, 0.5]]), t([[1, 1], [0, 1]])).item() == pytest.approx(0.375)


def test_ks_hand_values():
    # row maxima 0.3 and 0.6 -> 0.45
    pred = t([[0.2, 1.0], [0.9, 1.0]])
    true = t([[0.5, 1.0], [0.3, 1.0]])
    assert losses.ks(pred, true).item() == pytest.approx(0.45)


def test_kl_directions_hand_values():
    log_pred = torch.log(t([[0.5, 0.5]]))
    target = t([[0.25, 0.75]])
    rev = 0.5 * math.log(0.5 / 0.25) + 0.5 * math.log(0.5 / 0.75)
    fwd = 0.25 * math.log(0.25 / 0.5) + 0.75 * math.log(0.75 / 0.5)
    assert losses.kl_pred_target(log_pred, target).item() == pytest.approx(rev, abs=1e-12)
    assert losses.kl_target_pred(log_pred, target).item() == pytest.approx(fwd, abs=1e-12)
    assert rev != pytest.approx(fwd)


def test_kl_zero_for_equal_distributions():
    p = t([[0.2, 0.3, 0.5]])
    assert losses.kl_pred_target(torch.log(p), p).item() == pytest.approx(0.0, abs=1e-12)
    assert losses.kl_target_pred(torch.log(p), p).item() == pytest.approx(0.0, abs=1e-12)


def test_kl_with_empty_target_bin_uses_floor():
    # target [1, 0], prediction [0.5, 0.5]: KL(p̂||p) = 0.5 ln(0.5/1) + 0.5 ln(0.5/floor)
    log_pred = torch.log(t([[0.5, 0.5]]))
    target = t([[1.0, 0.0]])
    want = 0.5 * math.log(0.5) + 0.5 * math.log(0.5 / losses.LOG_FLOOR)
    assert losses.kl_pred_target(log_pred, target).item() == pytest.approx(want, rel=1e-12)
    # forward direction ignores the empty bin: 1 * ln(1 / 0.5)
    assert losses.kl_target_pred(log_pred, target).item() == pytest.approx(math.log(2.0), rel=1e-12)


def _all_terms_grad(logits, target_pmf):
    logits = logits.clone().requires_grad_(True)
    log_pmf = torch.log_softmax(logits, dim=-1)
    pmf = torch.exp(log_pmf)
    weights = {name: 1.0 for name in losses.TERMS}
    total, parts = losses.composite(
        weights, pmf, log_pmf, torch.cumsum(pmf, -1), target_pmf, torch.cumsum(target_pmf, -1)
    )
    total.backward()
    return total, parts, logits.grad


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_one_hot_targets_and_huge_logits_stay_finite(dtype):
    bins = 360
    target = torch.zeros(3, bins, dtype=dtype)
    target[0, 0] = 1.0
    target[1, 359] = 1.0
    target[2, 100] = 1.0
    logits = torch.zeros(3, bins, dtype=dtype)
    logits[0, 200] = 1e4  # all predicted mass far from the target's single bin
    logits[1] = -1e4
    logits[1, 359] = 1e4  # exact hit with saturated softmax
    logits[2] = torch.linspace(-3e4, 3e4, bins, dtype=dtype)
    total, parts, grad = _all_terms_grad(logits, target)
    assert torch.isfinite(total)
    assert all(torch.isfinite(v) for v in parts.values())
    assert torch.isfinite(grad).all()
    # the miss costs about -ln(floor) in KL(p̂||p); the exact hit costs nothing there
    assert parts["pmf_kl"].item() > 0


def test_composite_is_weighted_sum():
    p = t([[0.5, 0.5]])
    q = t([[0.25, 0.75]])
    total, parts = losses.composite({"pmf_mse": 2.0, "cdf_ks": 0.5}, p, None, p.cumsum(-1), q, q.cumsum(-1))
    assert parts["pmf_mse"].item() == pytest.approx(0.0625)
    assert parts["cdf_ks"].item() == pytest.approx(0.25)
    assert total.item() == pytest.approx(2.0 * 0.0625 + 0.5 * 0.25)


def test_check_terms():
    losses.check_terms({"cdf_mse": 1.0, "pmf_kl": 1.0}, has_log_pmf=True)
    with pytest.raises(ValueError, match="unknown"):
        losses.check_terms({"nope": 1.0}, has_log_pmf=True)
    with pytest.raises(ValueError, match="softmax"):
        losses.check_terms({"pmf_kl": 1.0}, has_log_pmf=False)
    with pytest.raises(ValueError):
        losses.check_terms({}, has_log_pmf=True)
