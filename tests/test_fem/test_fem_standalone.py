"""The FEM without the ``ancf`` package: its standalone error tree (fem_reference._standalone_errors) and its
figure-title text (fem_reference.render) behave exactly like the product's own (ancf.errors, ancf.textfmt),
which they stand in for.  That fem_reference imports and solves with ancf absent: tests/test_layout.py."""

import inspect
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ancf.errors as product
import fem_reference._standalone_errors as standalone
from ancf import textfmt
from fem_reference import render

NAMES = ("BellowsError", "ConfigError", "InputError", "LimitError", "ConvergenceError", "UnstableEquilibriumError")


def _lineage(cls) -> list[str]:
    """The class's MRO by name, with builtins named as such (the two trees differ only in their module)."""
    return [c.__name__ if c.__module__ != "builtins" else f"builtins.{c.__name__}" for c in cls.__mro__]


@pytest.mark.parametrize("name", NAMES)
def test_standalone_tree_has_the_products_names_bases_and_constructors(name):
    ours, theirs = getattr(standalone, name), getattr(product, name)
    assert ours is not theirs
    assert _lineage(ours) == _lineage(theirs)
    assert inspect.signature(ours.__init__) == inspect.signature(theirs.__init__)


def test_standalone_errors_read_like_the_products():
    kw = dict(solver="fem", iterations=7, residual_norm=3.2e-4, tolerance=1e-8, history=[1.0, 3.2e-4])
    assert str(standalone.ConvergenceError("did not converge", **kw)) == str(product.ConvergenceError(
        "did not converge", **kw))
    kw = dict(solver="fem modes", min_eigenvalue=-2.5)
    assert str(standalone.UnstableEquilibriumError("saddle", **kw)) == str(product.UnstableEquilibriumError(
        "saddle", **kw))


_VALUES = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6), st.booleans(), st.none(),
    st.text(max_size=3), st.complex_numbers(allow_nan=False, allow_infinity=False, max_magnitude=10),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
    st.lists(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=2), min_size=1, max_size=3))


def _outcome(check, error, value, shape):
    try:
        return "ok", check("x", value, shape)
    except error:
        return "error", None


@settings(max_examples=300, deadline=None)
@given(value=_VALUES, shape=st.sampled_from([None, (), (3,), (2,)]))
def test_standalone_check_finite_accepts_and_refuses_what_the_products_does(value, shape):
    ours = _outcome(standalone.check_finite, standalone.InputError, value, shape)
    theirs = _outcome(product.check_finite, product.InputError, value, shape)
    assert ours[0] == theirs[0], (value, shape)
    if ours[0] == "ok":
        assert ours[1].dtype == np.float64 and ours[1].flags.c_contiguous
        np.testing.assert_array_equal(ours[1], theirs[1])


_NUMBERS = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=300, deadline=None)
@given(v=st.lists(_NUMBERS, min_size=0, max_size=4), scale=st.sampled_from([1.0, 1e3, 1e-3]),
       digits=st.integers(0, 4))
def test_render_title_numbers_are_the_products_text(v, scale, digits):
    assert render._vector(v, scale, digits) == textfmt.vector(v, None, scale, digits)
    for x in v:
        assert render._num(x, digits) == textfmt.number(x, None, 1.0, digits)


def test_render_title_rounds_minus_zero_and_names_non_finite():
    assert render._num(-0.04) == "0.0" and render._num(-0.05001) == "-0.1"
    assert [render._num(x) for x in (math.nan, math.inf, -math.inf)] == ["nan", "inf", "-inf"]
