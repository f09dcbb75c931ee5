"""The estimator's parameters: names from the signature, one declared constraint each, the messages."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import ModelError
from ipromp_pin.promp import IProMP

BAD = [
    ({"noise": 0.0}, "noise must be 'auto' or a positive float, got 0.0"),
    ({"noise": "x"}, "noise must be 'auto' or a positive float, got 'x'"),
    ({"noise": float("inf")}, "noise must be 'auto' or a positive float, got inf"),
    ({"temperature": 1.5}, "temperature must be 'auto' or a float in (0, 1], got 1.5"),
    ({"temperature": "same"}, "temperature must be 'auto' or a float in (0, 1], got 'same'"),
    ({"condition_noise": "x"}, "condition_noise must be 'auto', 'same' or a positive float, got 'x'"),
    ({"condition_noise": -1.0}, "condition_noise must be 'auto', 'same' or a positive float, got -1.0"),
    ({"pooling": 1.5}, "pooling must be in [0, 1], got 1.5"),
    ({"coupling": "some"}, "coupling must be 'auto', 'all' or a list of observed groups, got 'some'"),
    ({"coupling": ["a", "a"]}, "coupling ['a', 'a'] must list distinct observed groups (['a', 'b'])"),
    ({"coupling": ["c"]}, "coupling ['c'] must list distinct observed groups (['a', 'b'])"),
    ({"n_alpha": 2}, "n_alpha must be an integer >= 3, got 2"),
    ({"n_alpha": 3.0}, "n_alpha must be an integer >= 3, got 3.0"),
    ({"n_points": 100_001}, "n_points must be an integer in [2, 100000], got 100001"),
    ({"n_basis": True}, "n_basis must be an integer >= 2, got True"),
    ({"blas_threads": 0}, "blas_threads must be None or an integer in [1, 1024], got 0"),
    ({"blas_threads": "many"}, "blas_threads must be None or an integer in [1, 1024], got 'many'"),
    ({"task_prior": {"t": -1}}, "task_prior must map task names to non-negative numbers, got {'t': -1}"),
    ({"task_prior": [0.5]}, "task_prior must map task names to non-negative numbers, got [0.5]"),
    ({"ridge": float("nan")}, "ridge must be a finite number, got nan"),
    ({"margin": "1"}, "margin must be a finite number, got '1'"),
    ({"alpha_width": np.inf}, "alpha_width must be a finite number, got inf"),
    ({"observe": ["a", "robot"]}, "the robot group 'robot' cannot be an observed group"),
]


@pytest.mark.parametrize(("params", "message"), BAD)
def test_a_bad_parameter_is_refused_with_its_one_line_message(params, message):
    with pytest.raises(ModelError) as info:
        IProMP(["a", "b"]).set_params(**params).check_params()
    assert str(info.value) == message


def test_good_parameters_parse_the_groups_and_the_coupling():
    model = IProMP("a,b", coupling=("b",), noise=np.float32(2.0), n_basis=np.int64(9), task_prior={"t": 1})
    assert model.check_params() == (["a", "b"], ["b"])
    single = IProMP(["a"], coupling="all", temperature=1, condition_noise="same")
    assert single.check_params() == (["a"], "all")


def test_parameter_names_come_from_the_signature_and_each_has_one_constraint_entry():
    names = IProMP._get_param_names()
    assert names[:3] == ("observe", "n_basis", "width") and names[-1] == "blas_threads"
    assert set(IProMP._parameter_constraints) == set(names)
    assert list(IProMP().get_params()) == list(names)
    with pytest.raises(ModelError, match="unknown parameter 'nope'"):
        IProMP().set_params(nope=1)

    class Wider(IProMP):
        def __init__(self, observe=("a",), extra: int = 3) -> None:
            super().__init__(observe)
            self.extra = extra

    assert Wider._get_param_names() == ("observe", "extra")
    assert Wider(extra=5).get_params() == {"observe": ("a",), "extra": 5}


def test_fitted_attributes_are_read_only_and_absent_before_fit():
    model = IProMP(["a", "b"])
    assert not hasattr(model, "tasks_") and not hasattr(model, "basis_")
    with pytest.raises(AttributeError, match="tasks_"):
        model.tasks_  # noqa: B018
    with pytest.raises(AttributeError, match="read-only"):
        model.tasks_ = ["x"]
