"""Method settings read from the run's options (millimpact.methods.options): every spelling the
unused-options check accepts is read, so none is reported as used while the run ignores it."""
import pytest

from millimpact.errors import InputError
from millimpact.integration.solvers import reset_option_usage, unused_options
from millimpact.methods.options import float_option, peek, take


@pytest.mark.parametrize("spelling", ["free_phase", "-free_phase", "impact_free_phase", "-impact_free_phase"])
def test_a_setting_is_read_in_every_spelling(spelling):
    """``-impact_free_phase step`` was counted as read (its key normalizes to free_phase) but
    popped under the raw key alone, so the run silently took the default free phase."""
    reset_option_usage()
    options = {spelling: "step", "ksp_type": "cg"}
    assert peek(options, "free_phase") == "step"
    assert take(options, "free_phase") == "step"
    assert options == {"ksp_type": "cg"}             # the rest goes on to the solvers
    assert take(options, "free_phase") is None
    used = unused_options({spelling: "step"})
    assert used is None or used == []                # read: not reported (None: PETSc's record unreachable)


def test_the_last_spelling_wins_and_bad_values_name_the_option():
    options = {"t_end": "1e-4", "impact_t_end": "2e-4"}
    assert float_option(options, "t_end", 0.0) == 2e-4 and options == {}
    with pytest.raises(InputError, match="option t_end = 'soon': must be a number"):
        float_option({"-impact_t_end": "soon"}, "t_end", 0.0)
