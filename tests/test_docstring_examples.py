"""The Examples sections of the estimators' docstrings run and print what they show (issue 37):
every public estimator class has one, and each is a doctest of its module."""

import doctest
import importlib
import inspect

import pytest

import switchest.estimators as estimators

BASES = {"Estimator", "ModeBankFilter", "Method"}  # an abstract base and the registry's rows
CLASSES = [name for name, obj in ((name, getattr(estimators, name)) for name in estimators.__all__)
           if name not in BASES and inspect.isclass(obj) and hasattr(obj, "run")]
MODULES = sorted({getattr(estimators, name).__module__ for name in CLASSES})


def test_every_public_estimator_class_has_an_examples_section():
    missing = [name for name in CLASSES
               if "    Examples\n    --------\n" not in (getattr(estimators, name).__doc__ or "")]
    assert len(CLASSES) >= 11 and not missing, missing


@pytest.mark.parametrize("module", MODULES)
def test_the_examples_run(module):
    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS,
                             raise_on_error=False, verbose=False)
    assert result.attempted > 0 and result.failed == 0
