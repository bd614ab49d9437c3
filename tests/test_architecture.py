"""The house rules of issue 33 ("Rules that change"), checked over ``tmm_core`` and ``cosim``:

* no import cycle, every import counted (those inside functions too);
* functions of at most 80 lines of code (docstrings, comments and blank lines do not count:
  documentation counts toward no limit) and at most 20 parameters;
* the public entry points of ``tmm_core`` (its ``__all__``) take at most 8 parameters (data
  classes count their fields: a record's fields are its parameters).

What breaks a rule today is listed below with its reason; the lists may only shrink. A new
violation fails, and so does an entry that no longer violates (remove it: the rule then holds
there for good)."""
import ast
import dataclasses
import pickle
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("tmm_core", "cosim")
MAX_LINES, MAX_PARAMETERS = 80, 20

#: Import cycles allowed for now, each a set of modules, with the reason.
CYCLES: dict = {}

#: Functions over the limits for now: "module.function" -> reason.
LONG_FUNCTIONS = {
    "tmm_core.compiled.march.march": "the compiled march of the time step (8 records): the step loop around the second-order iteration with Anderson mixing, its scratch arrays allocated once per march (the integrator and history loads are shared helpers)",
    "tmm_core.compiled.riccati.factor_configuration": "compiled factorization of one configuration (7 records), one loop over the chain; issue 33",
    "tmm_core.compiled.step_data.solve_loads_many": "compiled load solve of many load sets (6 records), one sweep; issue 33",
    "tmm_core.compiled.periodic.push": "compiled linearized step (9 records): the Jacobian of the second-order iteration assembled from its sparse segment blocks (the integrator and history loads are shared helpers)",
    "tmm_core.compiled.reduced_periodic.revolution": "reduced model's Radau IIA revolution (10 records); issue 33 item 4",
    "tmm_core.compiled.structure.solve_loads": "compiled load solve of one load set (6 records), one sweep; issue 33",
    "tmm_core.linkage_kinematics.solve": "Shin's module kinematics in closed form; issue 33",
    "tmm_core.linkage_plan.plan_modules": "the module plan of a general linkage; issue 33",
}


#: Public entry points over 8 parameters for now: name -> reason.
WIDE_ENTRY_POINTS = {
    "Link": "a link's fields (span, mesh, masses, damping, end blocks); issue 33 item 5 (records)",
    "LinkageMechanism": "a general linkage's parts; issue 33 item 5",
    "Member": "a member's fields; issue 33 item 5",
    "KEDResult": "a result record (its fields are outputs, not options)",
    "ReducedBasis": "a data record made by build_basis (its fields are the basis' arrays and counts, not options)",
    "quasi_static": "mechanism, angles, speed and the model options; issue 33 item 1 (a model built once)",
    "TimeDomain": "the model options, the keywords of the facade of discretization.discretize; issue 33 item 5",
    "periodic_steady_state_reduced": "solver options; issue 33 item 5",
}
MAX_PUBLIC_PARAMETERS = 8

#: Each compiled entry point beside the numpy reference it mirrors and the test that holds them
#: equal (to 1e-12 relative unless the test says otherwise): (compiled, numpy reference, test).
PAIRS = (
    ("compiled.structure.solve_range (binding.static_solve)", "structure.solve_linear, statics.solve_static",
     "tests/test_kernels.py::test_compiled_factorization_equals_numpy_for_a_beam_column_solve"),
    ("compiled.structure.solve_range, compiled.dense.iteration_start (binding.static_solve; beam-column iteration)",
     "ked.quasi_static (numpy beam-column iteration)",
     "tests/test_kernels.py::test_compiled_quasi_static_revolution_equals_numpy"),
    ("compiled.step_data.solve_loads_many (load-to-response maps)", "step_data.numpy_maps",
     "tests/test_kernels.py::test_compiled_configuration_maps_equal_numpy"),
    ("compiled.time_step.factor_range, factored_solve (binding.factored)", "time_step.solve_step (numpy step)",
     "tests/test_kernels.py::test_compiled_march_on_stored_factorizations_equals_numpy_over_a_revolution"),
    ("compiled.march.march (binding.march)", "time_step.solve_step, step_loads (numpy step), integrators",
     "tests/test_kernels.py::test_compiled_march_equals_numpy_for_every_integrator_and_the_quasi_static_axial_force"),
    ("compiled.integrators.history, advance and compiled.time_step.history_loads (binding.step_parts; the march's "
     "and the linearized revolutions' shared step parts)", "integrators (every integrator), time_step.step_loads",
     "tests/test_kernels.py::test_compiled_march_equals_numpy_for_every_integrator_and_the_quasi_static_axial_force"),
    ("compiled.periodic.push, velocities (binding.linearized)", "periodic (batched numpy linearized step)",
     "tests/test_periodic.py::test_compiled_linearized_revolutions_match_numpy"),
    ("compiled.reduced_periodic.revolution (binding.reduced_revolution)", "reduced_periodic.ReducedModel (numpy)",
     "tests/test_reduced.py::test_compiled_revolution_matches_the_numpy_reference"),
)


def _modules() -> dict:
    out = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _target(module: str, node: ast.ImportFrom | ast.Import, is_package: bool) -> list:
    """The project modules an import statement of ``module`` loads."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name in MODULES]
    base = module.split(".") if is_package else module.split(".")[:-1]
    if node.level:
        base = base[:len(base) - (node.level - 1)] if node.level > 1 else base
        stem = ".".join(base + ([node.module] if node.module else []))
    else:
        stem = node.module or ""
    found = [f"{stem}.{a.name}" for a in node.names if f"{stem}.{a.name}" in MODULES]
    return found + ([stem] if stem in MODULES and len(found) < len(node.names) else [])


def _graph() -> dict:
    graph = {}
    for module, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        targets = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                targets.update(_target(module, node, path.name == "__init__.py"))
        graph[module] = targets - {module}
    return graph


def _cycles(graph: dict) -> list:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(frozenset(component))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _code_lines(lines: list, node) -> int:
    body = node.body
    doc = set()
    if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
            and isinstance(body[0].value.value, str):
        doc = set(range(body[0].lineno, body[0].end_lineno + 1))
    return sum(1 for i in range(node.lineno, node.end_lineno + 1)
               if i not in doc and lines[i - 1].strip() and not lines[i - 1].strip().startswith("#"))


def _parameters(node) -> int:
    a = node.args
    n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + bool(a.vararg) + bool(a.kwarg)
    return n - (1 if a.args and a.args[0].arg in ("self", "cls") else 0)


def _oversized() -> dict:
    out = {}
    for module, path in MODULES.items():
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size, params = _code_lines(lines, node), _parameters(node)
                if size > MAX_LINES or params > MAX_PARAMETERS:
                    out[f"{module}.{node.name}"] = (size, params)
    return out


def test_no_new_import_cycle():
    cycles = _cycles(_graph())
    new = [sorted(c) for c in cycles if not any(c <= allowed for allowed in CYCLES)]
    assert not new, f"import cycles not allowed: {new}"
    gone = [sorted(a) for a in CYCLES if not any(c & a for c in cycles)]
    assert not gone, f"these cycles are gone: remove them from CYCLES: {gone}"


def test_functions_within_80_lines_and_20_parameters():
    found = _oversized()
    new = {k: v for k, v in found.items() if k not in LONG_FUNCTIONS}
    assert not new, f"over {MAX_LINES} lines of code or {MAX_PARAMETERS} parameters (lines, parameters): {new}"
    fixed = sorted(set(LONG_FUNCTIONS) - set(found))
    assert not fixed, f"within the limits now: remove them from LONG_FUNCTIONS: {fixed}"


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [frozenset("abc")]


@pytest.mark.parametrize("source, lines", [("def f():\n    '''doc\n    more'''\n    # why\n\n    return 1\n", 2)])
def test_documentation_counts_toward_no_limit(source, lines):
    node = ast.parse(source).body[0]
    assert _code_lines(source.splitlines(), node) == lines


def test_public_entry_points_take_few_parameters():
    import inspect

    import tmm_core
    wide = {}
    for name in tmm_core.__all__:
        obj = getattr(tmm_core, name)
        try:
            signature = inspect.signature(obj.__init__ if inspect.isclass(obj) else obj)
        except (TypeError, ValueError):
            continue
        n = len([p for p in signature.parameters if p not in ("self", "cls")])
        if n > MAX_PUBLIC_PARAMETERS:
            wide[name] = n
    new = {k: v for k, v in wide.items() if k not in WIDE_ENTRY_POINTS}
    assert not new, f"public entry points over {MAX_PUBLIC_PARAMETERS} parameters: {new}"
    fixed = sorted(set(WIDE_ENTRY_POINTS) - set(wide))
    assert not fixed, f"within the limit now: remove them from WIDE_ENTRY_POINTS: {fixed}"


def test_every_compiled_entry_point_has_its_reference_and_equality_test():
    """The compiled/reference pairs (:data:`PAIRS`, listed in docs/architecture.md) name tests
    that exist, every stage tmm_core.compiled.binding compiles is among them, and each compiled
    module has the numpy module of its name."""
    for compiled, reference, test in PAIRS:
        path, name = test.split("::")
        assert f"def {name}(" in (ROOT / path).read_text(encoding="utf-8"), test
    named = " ".join(compiled for compiled, _, _ in PAIRS)
    for stage in ("static_solve", "factored", "step_parts", "march", "linearized", "reduced_revolution"):
        assert f"binding.{stage}" in named, stage
    # Each compiled module mirrors the numpy module of the same name (dense: the small dense
    # algebra the references leave to numpy and scipy; ahead and __main__: the helper process
    # that compiles kernels ahead).
    for path in (ROOT / "tmm_core" / "compiled").glob("*.py"):
        if path.stem not in ("__init__", "__main__", "ahead", "binding", "cache", "dense"):
            assert (ROOT / "tmm_core" / f"{path.stem}.py").exists(), f"compiled/{path.name} mirrors no reference"


def _first_parameter(node):
    """The first parameter of a function other than ``self``/``cls`` (None without one)."""
    a = node.args
    params = a.posonlyargs + a.args
    if params and params[0].arg in ("self", "cls"):
        params = params[1:]
    return params[0] if params else (a.kwonlyargs[0] if a.kwonlyargs else None)


def test_no_function_takes_the_time_domain_facade_first():
    """Issue 33 item 1: the stages take the frozen model (``discretization.Discretization``), not
    the ``TimeDomain`` facade: no function of tmm_core or cosim takes a first parameter annotated
    with TimeDomain or named ``td``; the facade mixes nothing in."""
    found = []
    for module, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = _first_parameter(node)
                if first is None:
                    continue
                annotation = ast.unparse(first.annotation) if first.annotation is not None else ""
                if first.arg == "td" or "TimeDomain" in annotation:
                    found.append(f"{module}.{node.name}({first.arg}: {annotation or '-'})")
    assert not found, f"functions taking the TimeDomain facade first (take the model): {found}"
    from tmm_core import TimeDomain
    assert TimeDomain.__bases__ == (object,), "TimeDomain is a facade over the model, no mixin"


def test_the_discretization_is_frozen():
    """The model (issue 33 item 1) is a frozen record: no field is rebound, its mappings and the
    arrays no kernel reads are read-only, and it pickles (an engine crosses process boundaries)."""
    from scenarios.rigs import alexander_lawrence
    from tmm_core import TimeDomain
    from tmm_core.discretization import Discretization
    assert Discretization.__dataclass_params__.frozen
    td = TimeDomain(alexander_lawrence(2), backend="numpy")
    with pytest.raises(dataclasses.FrozenInstanceError):
        td.model.n_dof = 0
    with pytest.raises(TypeError):
        td.model.offsets[td.links[0].name] = 1
    with pytest.raises(ValueError):
        td.model.is_u[0] = False
    assert td.n_dof == td.model.n_dof and td.stack is not None
    copy = pickle.loads(pickle.dumps(td))
    assert copy.model.n_dof == td.n_dof and dict(copy.model.offsets) == dict(td.model.offsets)
    with pytest.raises(TypeError):
        copy.model.offsets[td.links[0].name] = 1
