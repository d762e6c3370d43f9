"""The grid connection, eq:power_balance."""

import pytest

from comems4build_ros.core.models import grid


def test_deficit_is_bought():
    buy, sell, residual = grid.exchange(500.0, 1200.0, 0.0, 0.0, 300.0, 400.0, 100.0)
    assert (buy, sell) == (900.0, 0.0) and residual == 0.0


def test_surplus_is_sold_never_both():
    buy, sell, residual = grid.exchange(300.0, 0.0, 200.0, 0.0, 2500.0, 0.0, 0.0)
    assert (buy, sell) == (0.0, 2000.0) and residual == 0.0


@pytest.mark.parametrize("flows", [(123.4, 0.1, 7.0, 2400.0, 55.5, 980.2, 0.3), (0.0,) * 7])
def test_balance_closes(flows):
    buy, sell, residual = grid.exchange(*flows)
    assert buy * sell == 0.0 and abs(residual) < 1e-9
