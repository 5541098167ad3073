"""The checks of the Python API's arguments (api.py, Plan.sample and the plan writers), the same ones
the CLI makes (apps/arg_checks.py calls them): each refuses a bad argument with one QmtInputError
line that names the argument and the fix, before any work, so nothing a caller passes ends their
process (a SystemExit from a Drake assertion) or exhausts memory.

- `strict_call`: a decorator turning a call's binding failure (a misspelt or missing keyword, too
  many arguments: Python's TypeError) into one line naming the keyword and the closest known one;
- `number`: a real number (not a bool, not a string), finite, in a range, an integer if asked;
- `path_arg`: a file path (str or os.PathLike, not empty);
- `times`: sample times [s], finite real numbers;
- `check_options`: a planner's keywords against its signature (unknown ones with the closest match),
  each value's type from its default and its range from OPTION_RANGES.
"""

from __future__ import annotations

import difflib
import functools
import inspect
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from qmt_drake.config.fields import is_number, show
from qmt_drake.errors import QmtInputError

F = TypeVar("F", bound=Callable[..., Any])  # strict_call keeps the decorated function's type

# Ranges of the planners' size options: (minimum, maximum, what the option is / the fix). A maximum is
# where a run stops being a plan and becomes a budget question (budgets.py prices the GA's population
# and generations, the energy planner's m and divisions; these are the rest).
OPTION_RANGES: dict[str, tuple[float, float, str]] = {
    "population": (2, 10 ** 12, "the GA needs at least 2 chromosomes to cross (default 40); budgets.py prices it"),
    "generations": (1, 10 ** 9, "run at least one generation (default 150)"),
    "max_generations": (1, 10 ** 9, "run at least one generation"),
    "stall": (0, 10 ** 9, "0 never stops early"),
    "stall_generations": (0, 10 ** 9, "0 never stops early"),
    # TOPP-RA's grid: ~0.1 ms per grid point and path on a UR5 (1000 points: 0.1-0.3 s); 10^5 is minutes
    "n_grid": (10, 10 ** 5, "TOPP-RA's grid points per path (default 1000)"),
    "grid_points": (10, 10 ** 5, "TOPP-RA's grid points (default 200)"),
    "restarts": (1, 1000, "the family optimum's restarts (default 1)"),
    "starts": (1, 10 ** 4, "the optimum's starts (default 24)"),
    "polished": (0, 10 ** 4, "the optimum's polished starts (default 6)"),
    "control_points": (4, 1000, "the B-spline's control points (default 16)"),
    "num_control_points": (4, 1000, "the B-spline's control points (default 16)"),
    "constraint_samples": (2, 10 ** 5, "samples of the constraints (default 80)"),
    "tilt_samples": (2, 10 ** 5, "samples of the tilt constraint (default 40)"),
    "polygon_sides": (3, 10 ** 4, "sides of the moment polygon (default 32)"),
    "path_knots": (2, 10 ** 5, "knots of the path (default 400)"),
    "major_iterations": (1, 10 ** 7, "SNOPT's major iterations (default 500)"),
    "max_iter": (1, 10 ** 8, "steepest descent's iterations (default 20000)"),
    "m": (1, 200, "Fourier terms per joint (the paper: 5)"),
    "divisions": (2, 10 ** 7, "time divisions of the integral (the paper: 40)"),
    "checkpoint_every": (1, 10 ** 9, "generations between checkpoints"),
    "seed": (0, 2 ** 63 - 1, "seeds are non-negative integers"),
}
REAL_RANGES: dict[str, tuple[float, float, str]] = {  # float options with a bounded meaning
    "jerk_limit": (1e-9, 1e12, "the Cartesian jerk limit [m/s^3] (default 10)"),
    "max_tilt_rad": (0.0, math.pi, "the tray's allowed tilt [rad] (default 0.02)"),
    "bisection_rtol": (1e-15, 0.5, "the bisection's relative tolerance (default 1e-4)"),
    "velocity_limit_scale": (1e-9, 1e12, "a scale of the velocity limits"),
    "max_motion_time_s": (1e-6, 1e6, "an upper bound of the motion time [s]"),
    "progress_every_s": (0.0, 1e9, "seconds between progress lines"),
    "c1": (0.0, 1e12, "the energy weight (>= 0)"),
    "c2": (0.0, 1e12, "the time weight (>= 0)"),
}


def _closest(name: str, known) -> str:
    near = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f"did you mean {near[0]!r}? " if near else ""


def strict_call(func: F) -> F:
    """A public function whose binding errors (unknown, missing or surplus arguments) raise one
    QmtInputError line naming the argument, the closest known keyword and the call's keywords."""
    sig = inspect.signature(func)
    names = [n for n, p in sig.parameters.items() if p.kind is not p.VAR_KEYWORD]
    open_kw = any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            sig.bind(*args, **kwargs)
        except TypeError as exc:
            text = str(exc)
            unknown = [k for k in kwargs if k not in names] if not open_kw else []
            if unknown:
                raise QmtInputError(f"{func.__name__}: unknown keyword {unknown[0]!r}; {_closest(unknown[0], names)}"
                                    f"it takes {', '.join(names)}") from None
            raise QmtInputError(f"{func.__name__}: {text}; it takes ({', '.join(names)})") from None
        return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]  # functools.wraps keeps the signature


def number(value: Any, name: str, *, minimum: float | None = None, maximum: float | None = None,
           positive: bool = False, integer: bool = False, fix: str = "") -> Any:
    """`value` as a checked number (an int when `integer`): a real number, not a bool or a string,
    finite, > 0 when `positive`, in [minimum, maximum]. The message says `name VALUE must ...; fix`."""
    tail = f"; {fix}" if fix else ""
    if integer:
        if not (isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))):
            raise QmtInputError(f"{name} {show(value)} must be an integer{tail}")
        value = int(value)
    elif not is_number(value):
        raise QmtInputError(f"{name} {show(value)} must be a number{tail}")
    elif not math.isfinite(float(value)) or (positive and not value > 0):
        raise QmtInputError(f"{name} {value} must be a finite {'positive ' if positive else ''}number{tail}")
    if minimum is not None and value < minimum:
        raise QmtInputError(f"{name} {value} must be >= {minimum}{tail}")
    if maximum is not None and value > maximum:
        raise QmtInputError(f"{name} {value} must be <= {maximum:g}{tail}")
    return value


def path_arg(value: Any, name: str, what: str = "file") -> Path:
    """A path given as str or os.PathLike (not empty, no NUL byte)."""
    if not isinstance(value, (str, os.PathLike)) or isinstance(value, bytes):
        raise QmtInputError(f"{name}: got {show(value)}; give the path of a {what} (a str or pathlib.Path)")
    text = os.fspath(value)
    if not isinstance(text, str) or not text or "\0" in text:
        raise QmtInputError(f"{name}: got {show(value)}; give the path of a {what} (a non-empty str)")
    return Path(text)


def times(t_s: Any, name: str = "t_s") -> Any:
    """Sample times [s]: a real number or an array of them, all finite (NaN would reach a Drake
    assertion that ends the process). Returned unchanged in form (a scalar stays a scalar)."""
    if is_number(t_s):
        if not math.isfinite(float(t_s)):
            raise QmtInputError(f"{name} {t_s} must be a finite time [s] (0 to the plan's motion_time_s)")
        return t_s
    try:
        a = np.asarray(t_s)
    except (TypeError, ValueError):  # ragged nesting and the like
        raise QmtInputError(f"{name}: got {show(t_s)}; give a time [s] or an array of times") from None
    if a.dtype.kind not in "iuf" or a.size == 0:
        raise QmtInputError(f"{name}: got {show(t_s)}; give a time [s] or a non-empty array of times (numbers)")
    if a.ndim > 1:  # a spatial plan's Drake call refused it (a TypeError), a planar one answered a (1, K, n) shape
        raise QmtInputError(f"{name}: got an array of shape {a.shape}; give a time [s] or a 1-D array of times "
                            "(e.g. np.ravel it)")
    if not np.all(np.isfinite(a)):
        raise QmtInputError(f"{name} must be finite times [s]; got {show(t_s)}")
    return t_s


def option_value(key: str, value: Any, default: Any, name: str) -> Any:
    """One planner keyword (`name` names it in the message) checked by its default's type and its range
    (OPTION_RANGES, REAL_RANGES)."""
    if value is None and default is None:  # None: the planner's own default
        return None
    if key in OPTION_RANGES or (isinstance(default, int) and not isinstance(default, bool)):
        lo, hi, fix = OPTION_RANGES.get(key, (0, 10 ** 9, "a count"))
        return number(value, name, minimum=lo, maximum=hi, integer=True, fix=fix)
    if key in REAL_RANGES or isinstance(default, float):
        lo, hi, fix = REAL_RANGES.get(key, (-1e12, 1e12, "a finite number"))
        return number(value, name, minimum=lo, maximum=hi, fix=fix)
    if isinstance(default, bool) and not isinstance(value, (bool, np.bool_)):
        raise QmtInputError(f"{name} {show(value)} must be True or False")
    if isinstance(default, str) and not isinstance(value, str):
        raise QmtInputError(f"{name} {show(value)} must be a string (default {default!r})")
    return value


def check_options(func: Callable, options: dict, where: str, planner: str, *, skip=()) -> None:
    """`options` against `func`'s keywords (minus `skip`): an unknown one refused with the closest known
    keyword, then each value by option_value. A function taking **kwargs accepts any key. `where`
    names the options ("plan_with option", "--option"), `planner` the planner ("the spatial ga planner")."""
    sig = inspect.signature(func)
    params = {k: p for k, p in sig.parameters.items()
              if k not in skip and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    if not any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        known = sorted(params)
        for key in options:
            if key not in known:
                raise QmtInputError(f"{where} {key}: not an option of {planner}; {_closest(key, known)}"
                                    f"it takes {', '.join(known) or 'no options'}")
    for key, value in options.items():
        if key in params and not callable(value):
            default = params[key].default
            option_value(key, value, None if default is inspect.Parameter.empty else default, f"{where} {key}")
