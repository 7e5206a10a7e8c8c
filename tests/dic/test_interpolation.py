import pytest

from livedic.dic.bspline import DEGREES
from livedic.dic.interpolation import BSPLINE3, BSPLINE5, DEFAULT_INTERPOLATION, INTERPOLATIONS, Interpolation


def test_parse_names_and_degrees():
    assert Interpolation.parse(None) == Interpolation(DEFAULT_INTERPOLATION) == Interpolation.parse(" BSPLINE3 ")
    assert Interpolation.parse("bspline5").degree == 5 and Interpolation.parse(BSPLINE3).degree == 3
    assert str(Interpolation.parse("BSpline5")) == BSPLINE5
    assert Interpolation.parse(Interpolation(BSPLINE5)) == Interpolation(BSPLINE5)
    assert sorted(Interpolation(name).degree for name in INTERPOLATIONS) == sorted(DEGREES)
    assert "quintic" in Interpolation(BSPLINE5).describe() and "cubic" in Interpolation(BSPLINE3).describe()


@pytest.mark.parametrize("bad", ["bspline4", "cubic", "", "5", 5])
def test_bad_names_give_one_line_naming_the_choices(bad):
    with pytest.raises(ValueError, match="choose one of bspline3, bspline5") as info:
        Interpolation.parse(bad)
    assert "\n" not in str(info.value)
