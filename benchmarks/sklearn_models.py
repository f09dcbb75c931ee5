"""The model's own small regressions against scikit-learn's estimators on the problems a training poses.

Run ``taskset -c 0 python benchmarks/sklearn_models.py``. It fits the default model (paper setting,
3 tasks of 20 synthetic demos, as ``ab_compare.py`` does) once while recording every problem handed
to the recognition head's logistic regression (``head.fit_softmax``, its paths of warm-started
``C``) and LDA (``head.fit_lda``) and to the hand-over's ridge (``handover.fit_ridge``) and
k-nearest-neighbour (``handover.fit_knn``) regressions, then solves every recorded problem with ours
and with scikit-learn's estimator set up to give the same answer (``LogisticRegression`` with the row
weights and warm starts; ``LinearDiscriminantAnalysis(solver="lsqr")`` with the Ledoit-Wolf shrinkage
of ``sklearn.covariance``, unweighted since it takes no row weights; ``RidgeCV`` on standardised
features with its leave-one-out predictions; ``KNeighborsRegressor`` with ``cross_val_predict`` over
``LeaveOneOut`` for every candidate ``k`` and weighting). Prints per model the fits of one training,
the seconds all of them take with each (fastest of ``--repeats``; scikit-learn's k-nearest-neighbour
leave-one-out on ``--knn-problems`` problems, scaled to all) and their ratio, and the largest
difference of the answers. ``--smoke``: 2 tasks of 5 demos, numpy kernels, one repeat, 12 problems
per model: seconds.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections.abc import Callable

import numpy as np
from checkouts import smoke_kernels
from threadpoolctl import threadpool_limits

OBSERVE = ["orientation", "emg"]
SMOKE_PROBLEMS = 12
"""Problems per model that ``--smoke`` compares."""


def record(n_tasks: int, n_train: int) -> dict[str, list[tuple]]:
    """The arguments of every call of the four fits during one training."""
    from ab_compare import training_data

    from ipromp_pin.promp import handover_selection, head

    calls: dict[str, list[tuple]] = {"softmax": [], "lda": [], "ridge": [], "knn": []}
    originals = {
        (head, "fit_softmax", "softmax"): head.fit_softmax,
        (head, "fit_lda", "lda"): head.fit_lda,
        (handover_selection, "fit_ridge", "ridge"): handover_selection.fit_ridge,
        (handover_selection, "fit_knn", "knn"): handover_selection.fit_knn,
    }

    def recorder(name: str, fit: Callable) -> Callable:
        def wrapped(*args, **kwargs):
            calls[name].append((args, kwargs))
            return fit(*args, **kwargs)

        return wrapped

    for (module, attr, name), fit in originals.items():
        setattr(module, attr, recorder(name, fit))
    try:
        estimator, train, _ = training_data("ipromp_pin", n_tasks, n_train)
        estimator(OBSERVE, noise=10.0, blas_threads=None).fit(train)
    finally:
        for (module, attr, _), fit in originals.items():
            setattr(module, attr, fit)
    return calls


def fastest(run: Callable[[], object], repeats: int) -> float:
    """The fastest of ``repeats`` runs, in [s]."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return min(times)


def softmax_paths(calls: list[tuple]) -> list[tuple]:
    """The recorded logistic regressions as paths (x, y, T, weight, [C, ...]): a call without a start
    begins a path, a warm-started one continues it."""
    paths: list[tuple] = []
    for args, kwargs in calls:
        x, y, n_classes, c = args[:4]
        rest = dict(zip(("weight", "start"), args[4:], strict=False)) | kwargs
        if rest.get("start") is None:
            paths.append((x, y, n_classes, rest.get("weight"), []))
        paths[-1][4].append(c)
    return paths


def compare_softmax(calls: list[tuple], repeats: int) -> tuple[float, float, float]:
    from sklearn.linear_model import LogisticRegression

    from ipromp_pin.promp.head import fit_softmax

    def ours(x, y, n_classes, weight, cs):
        theta, out = None, []
        for c in cs:
            w, b, theta = fit_softmax(x, y, n_classes, c, weight, theta)
            out.append((w, b))
        return out

    def library(x, y, n_classes, weight, cs):
        model, out = LogisticRegression(tol=1e-5, max_iter=500, warm_start=True), []
        for c in cs:
            model.set_params(C=2 * c if n_classes == 2 else c).fit(x, y, sample_weight=weight)
            w, b = model.coef_, model.intercept_
            if n_classes == 2:
                w, b = np.stack([-w[0] / 2, w[0] / 2]), np.array([-b[0] / 2, b[0] / 2])
            out.append((w, b))
        return out

    def proba(x, w, b):
        z = x @ w.T + b
        e = np.exp(z - z.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)

    t_ours = t_lib = diff = 0.0
    for path in softmax_paths(calls):
        t_ours += fastest(lambda p=path: ours(*p), repeats)
        t_lib += fastest(lambda p=path: library(*p), repeats)
        if len(np.unique(path[1])) == path[2]:  # every class among the rows: the same classes
            for (w1, b1), (w2, b2) in zip(ours(*path), library(*path), strict=True):
                diff = max(diff, float(np.abs(proba(path[0], w1, b1) - proba(path[0], w2, b2)).max()))
    return t_ours, t_lib, diff


def compare_lda(calls: list[tuple], repeats: int) -> tuple[float, float, float]:
    from sklearn.covariance import ledoit_wolf_shrinkage
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    from ipromp_pin.promp.head import fit_lda

    def library(x, y):
        labels = np.unique(y)
        means = np.stack([x[y == k].mean(axis=0) for k in labels])
        lam = ledoit_wolf_shrinkage(x - means[np.searchsorted(labels, y)], assume_centered=True)
        return LinearDiscriminantAnalysis(solver="lsqr", shrinkage=lam).fit(x, y)

    t_ours = t_lib = diff = 0.0
    for args, _ in calls:
        x, y, n_classes, weight = args[:4]
        t_ours += fastest(lambda a=args: fit_lda(*a), repeats)
        t_lib += fastest(lambda x=x, y=y: library(x, y), repeats)
        if n_classes > 2 and len(np.unique(y)) == n_classes:  # unweighted: the same problem
            coef, _ = fit_lda(x, y, n_classes, np.ones(y.size))
            diff = max(diff, float(np.abs(coef - library(x, y).coef_).max()))
    return t_ours, t_lib, diff


def compare_ridge(calls: list[tuple], repeats: int) -> tuple[float, float, float]:
    from sklearn.linear_model import RidgeCV
    from sklearn.preprocessing import StandardScaler

    from ipromp_pin.promp.handover import RIDGE_PENALTIES, fit_ridge

    def library(x, y):
        ridge = RidgeCV(alphas=RIDGE_PENALTIES, scoring="neg_mean_squared_error", store_cv_results=True)
        return ridge.fit(StandardScaler().fit_transform(x), y)

    t_ours = t_lib = diff = 0.0
    for args, _ in calls:
        x, y = args[:2]
        t_ours += fastest(lambda x=x, y=y: fit_ridge(x, y), repeats)
        t_lib += fastest(lambda x=x, y=y: library(x, y), repeats)
        fit, ref = fit_ridge(x, y), library(x, y)
        if fit.penalty == ref.alpha_:
            loo = y - ref.cv_results_[:, :, RIDGE_PENALTIES.index(fit.penalty)]
            diff = max(diff, float(np.abs(loo - fit.residuals).max()))
    return t_ours, t_lib, diff


def compare_knn(calls: list[tuple], repeats: int, problems: int) -> tuple[float, float, float]:
    from sklearn.model_selection import LeaveOneOut, cross_val_predict
    from sklearn.neighbors import KNeighborsRegressor
    from sklearn.preprocessing import StandardScaler

    from ipromp_pin.promp.handover import KNN_NEIGHBOURS, fit_knn

    def library(x, y):
        xs, best = StandardScaler().fit_transform(x), (np.inf, y)
        for k in KNN_NEIGHBOURS:
            if k > x.shape[0] - 1:
                break
            for weights in ("uniform", "distance"):
                model = KNeighborsRegressor(n_neighbors=k, weights=weights)
                resid = y - cross_val_predict(model, xs, y, cv=LeaveOneOut())
                best = min(best, (float(np.sum(resid * resid)), resid), key=lambda s: s[0])
        return best[1]

    t_ours = t_lib = diff = 0.0
    for args, _ in calls:
        t_ours += fastest(lambda a=args: fit_knn(*a), repeats)
    if calls:
        library(*calls[0][0][:2])  # imports and first calls outside the timing
    for args, _ in calls[:problems]:
        t_lib += fastest(lambda a=args: library(*a[:2]), 1)
        fit = fit_knn(*args)
        if fit is not None:
            diff = max(diff, float(np.abs(library(*args[:2]) - fit.residuals).max()))
    return t_ours, t_lib * len(calls) / max(1, min(problems, len(calls))), diff


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=3, help="number of tasks (default 3)")
    ap.add_argument("--repeats", type=int, default=3, help="runs of every problem (the fastest counts)")
    ap.add_argument("--knn-problems", type=int, default=3, help="k-NN problems scikit-learn solves")
    ap.add_argument("--smoke", action="store_true", help="tiny, numpy kernels: seconds")
    args = ap.parse_args(argv)
    n_train = 20
    if args.smoke:
        smoke_kernels("ipromp_pin")
        args.tasks, args.repeats, args.knn_problems, n_train = 2, 1, 1, 5
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scikit-learn's convergence warnings at max_iter
        calls = record(args.tasks, n_train)
        if args.smoke:  # every model compared, on a few of its problems
            calls = {key: problems[:SMOKE_PROBLEMS] for key, problems in calls.items()}
        print(f"{args.tasks} tasks of {n_train} synthetic demos; seconds per training (ours -> scikit-learn)")
        knn = compare_knn(calls["knn"], args.repeats, args.knn_problems)
        rows = [
            ("logistic regression (head)", "softmax", compare_softmax(calls["softmax"], args.repeats)),
            ("LDA (head, unweighted)", "lda", compare_lda(calls["lda"], args.repeats)),
            ("ridge regression (hand-over)", "ridge", compare_ridge(calls["ridge"], args.repeats)),
            ("k nearest neighbours (hand-over)", "knn", knn),
        ]
    for label, key, (t_ours, t_lib, diff) in rows:
        print(
            f"{label}: {len(calls[key])} fits, {t_ours:.3f} -> {t_lib:.3f} s "
            f"({t_lib / max(t_ours, 1e-12):.1f}x); largest difference {diff:.1e}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
