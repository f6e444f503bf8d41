"""The pytest plugin of pillar-xval: installing the toolkit enables it (entry point
``pytest11``).

It gives a test the fixture ``xval``::

    def test_bem_against_fem(xval):
        scene = xval.scene("single-pillar", "pillars.E_Pa=1.6e7")
        bem = xval.run("bem", scene, elements_per_diameter=11)
        fem = xval.run("fem-axisym", scene)
        assert_close(bem, fem, ("F_T",), rtol=0.01, source="measured 0.4 %")

Every run goes through the study engine into pytest's cache folder
(``.pytest_cache/d/pillar-xval``), so a rerun of an unchanged suite solves nothing; the
case key covers the scene, the model, its options and the toolkit's computing code, so a
change to any of them recomputes exactly the cases it touches.  Under pytest-xdist the
workers share that folder and the engine's per-case lock: no case is solved twice.

Options: ``--xval-fresh`` empties the cache before the session (recompute everything);
``--xval-executor serial|pool|dask`` says where cases run (default serial: the test's own
process).  The terminal summary lists every check of :mod:`validation.testing`: the
quantity, the value, the reference, the tolerance, and pass or fail, for the tests that use
the ``xval`` fixture.
"""

from __future__ import annotations

import shutil
from dataclasses import asdict
from pathlib import Path

import pytest

CACHE_NAME = "pillar-xval"
_EXECUTORS = ("serial", "pool", "dask")
_CHECK_PROPERTY = "pillar_xval_check"
_CONFIG: dict = {}  # the session's config, for hooks that are not handed it


def pytest_addoption(parser):
    group = parser.getgroup("pillar-xval", "pillar-xval tolerance checks")
    group.addoption("--xval-fresh", action="store_true", default=False,
                    help="recompute every pillar-xval case (empty the cache first)")
    group.addoption("--xval-executor", choices=_EXECUTORS, default="serial",
                    help="where pillar-xval cases run: serial (default), pool or dask")


def _cache_dir(config) -> Path:
    if getattr(config, "cache", None) is None:
        raise pytest.UsageError("pillar-xval keeps its cases in pytest's cache folder: do not "
                                "disable the cacheprovider plugin (-p no:cacheprovider)")
    return Path(config.cache.mkdir(CACHE_NAME))


def pytest_configure(config):
    _CONFIG["config"] = config
    config._xval_checks = []
    config._xval_counts = {"solved": 0, "cached": 0}
    # Only the controller (or a run without xdist) empties the cache, before any worker runs.
    if config.getoption("--xval-fresh") and not hasattr(config, "workerinput"):
        folder = _cache_dir(config)
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True, exist_ok=True)


class XVal:
    """What the ``xval`` fixture gives a test: scenes and cached runs on the study engine."""

    def __init__(self, config, test_dir: Path):
        self._config, self._test_dir = config, test_dir
        self.cache_dir = _cache_dir(config)
        self._engine = None

    def scene(self, preset_or_file: str, *overrides: str):
        """A preset by name, or a scene file (relative to the test file's folder), with
        ``table.key=value`` overrides."""
        from pillar_xval.scenes import load_scene, preset_names

        source = preset_or_file
        if source not in preset_names():
            path = Path(source)
            source = str(path if path.is_absolute() else self._test_dir / path)
        return load_scene(source, list(overrides))

    @property
    def engine(self):
        if self._engine is None:
            from .engine import Engine

            self._engine = Engine(self._config.getoption("--xval-executor"), quiet=True,
                                  label="xval")
        return self._engine

    def run(self, model: str, scene, **options):
        """The :class:`pillar_xval.outcome.ContactResult` of ``model`` on ``scene`` (computed
        once, then read from the cache); a case that failed raises its error.  An option the
        model does not take, or a value it refuses, is a pytest usage error naming it, before
        anything is solved; the pillar model defaults to the scene's (elastic on elastic
        pillars: :func:`validation.registry.scene_defaults`)."""
        from .engine import Case

        options = _checked(f"xval.run({model!r})", model, scene, options)
        outcome = self.engine.run_one(Case(model, scene, options), self.cache_dir)
        self._count(outcome)
        return outcome.unwrap()

    def converge(self, model: str, scene, levels: int = 3, coarsest=None, **options) -> dict:
        """A convergence study of ``model`` (``levels`` rungs of its ladder; ``options``: its
        other options, the same on every rung, checked as :meth:`run` checks them), for
        :func:`validation.testing.assert_agree` and :func:`~validation.testing.assert_order`."""
        from .studies._ladder import level_cases, study_levels

        from .registry import ladder_for

        call = f"xval.converge({model!r})"
        options = _checked(call, model, scene, options)
        refined = ladder_for(model).option
        if refined in options:
            raise pytest.UsageError(f"{call}: {refined} is the ladder's refined option: give "
                                    "its coarsest level as coarsest=")
        cases = level_cases(model, scene, levels, coarsest=coarsest, tag="xval",
                            options=options)
        outcomes = self.engine.run(cases, self.cache_dir)
        for outcome in outcomes:
            self._count(outcome)
        return study_levels(model, scene, outcomes)

    def _count(self, outcome) -> None:
        self._config._xval_counts["cached" if outcome.cached else "solved"] += 1

    def close(self) -> None:
        if self._engine is not None:
            self._engine.close()


def _checked(call: str, model: str, scene, options: dict) -> dict:
    """``options`` with the scene's defaults, once the registry accepts them; a
    pytest.UsageError naming the option otherwise (a misspelt option would otherwise be
    dropped by the solver and cached under a key that names it)."""
    from pillar_xval.scenes import InputError

    from .registry import check_options, scene_defaults

    try:
        check_options(model, options, "", scene)
    except InputError as exc:
        raise pytest.UsageError(f"{call}: {exc}") from None
    return scene_defaults(model, scene, options)


@pytest.fixture
def xval(request):
    """Scenes and cached model runs for tolerance checks (see :mod:`validation.pytest_plugin`)."""
    helper = XVal(request.config, Path(str(request.path)).parent)
    yield helper
    helper.close()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Hand each phase's checks to its report: under xdist they travel to the controller."""
    from .testing import checks_made

    outcome = yield
    report = outcome.get_result()
    checks = checks_made(clear=True)
    if "xval" not in getattr(item, "fixturenames", ()):
        return  # the summary lists the checks of tests that use the fixture
    for check in checks:
        report.user_properties.append((_CHECK_PROPERTY, {"test": item.nodeid,
                                                         **asdict(check)}))


def pytest_runtest_logreport(report):
    config = _CONFIG.get("config")
    if config is None:
        return
    for name, value in report.user_properties:
        if name == _CHECK_PROPERTY:
            config._xval_checks.append(value)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """xdist: add a worker's case counts to the controller's."""
    counts = getattr(node, "workeroutput", {}).get("xval_counts")
    config = _CONFIG.get("config")
    if counts and config is not None:
        for key, value in counts.items():
            config._xval_counts[key] += value


def pytest_sessionfinish(session):
    if hasattr(session.config, "workeroutput"):
        session.config.workeroutput["xval_counts"] = dict(session.config._xval_counts)


def pytest_terminal_summary(terminalreporter, config):
    checks, counts = config._xval_checks, config._xval_counts
    if not checks and not any(counts.values()):
        return
    from .output.formatting import aligned

    tr = terminalreporter
    tr.write_sep("=", "pillar-xval checks")
    if checks:
        rows = [("test", "check", "quantity", "value", "reference", "tolerance", "result")]
        for c in checks:
            rows.append((c["test"], c["name"], c["quantity"],
                         f"{c['value']:.6g}", f"{c['reference']:.6g}", c["tolerance"],
                         "pass" if c["passed"] else "FAIL"))
        for line in aligned(rows):
            tr.write_line(line)
        failed = sum(not c["passed"] for c in checks)
        tr.write_line(f"{len(checks)} checks, {failed} failed")
    if any(counts.values()):
        tr.write_line(f"xval cases: {counts['solved']} solved, {counts['cached']} from the "
                      f"cache ({_cache_dir(config)})")
