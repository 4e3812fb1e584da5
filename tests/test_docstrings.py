"""Public API documentation: numpydoc sections on every exported name, and no global matplotlib state.

Every function and class named in the ``__all__`` of a subpackage (and of the
top-level modules ``geometry`` and ``sensors``), and every public method those
classes define, is run through :func:`numpydoc.validate.validate`. The test
fails on these error codes:

* ``GL08``: the object has no docstring;
* ``SS01``: no one-line summary;
* ``PR01``: a parameter of the signature is not documented;
* ``PR02``: a documented parameter is not in the signature (docs drifting from code);
* ``PR04``: a documented parameter has no type (``name : type``);
* ``PR07``: a documented parameter has no description;
* ``RT01``: a function that returns a value has no Returns section;
* ``YD01``: a generator has no Yields section.

Extended summaries (``ES01``), See Also and Examples are not required here
(doctests run separately). Dataclasses, named tuples and protocols document
their fields in a Parameters or an Attributes section; the check is the same
(``PR01``: an undocumented field). Enums and exceptions are checked for a
docstring and a summary only.

A second test walks the syntax tree of every module under ``tudorvision/``
and fails on ``matplotlib.use(...)`` and on any import of
``matplotlib.pyplot``: plots draw on a :class:`matplotlib.figure.Figure` and
never switch a user's backend.
"""
from __future__ import annotations

import ast
import dataclasses
import enum
import importlib
import inspect
from pathlib import Path
from typing import Protocol

import pytest

numpydoc_validate = pytest.importorskip("numpydoc.validate")

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "tudorvision"

MODULES = ["tudorvision.robot", "tudorvision.io", "tudorvision.stereo", "tudorvision.rgbd", "tudorvision.servo",
           "tudorvision.catch", "tudorvision.joint", "tudorvision.sim", "tudorvision.lab", "tudorvision.geometry",
           "tudorvision.sensors"]

CHECKED = ("GL08", "SS01", "PR01", "PR02", "PR04", "PR07", "RT01", "YD01")

# Temporary known lists; the test reports an entry that no longer fails (documented, renamed or no longer
# exported), so they only shrink. Fix the docstring, then delete the entry.
#
# (a) Names defined in files that other work in progress rewrites: the security rework of
# joint/{protocol,server,adapter,transport,proxy,safety}.py, the strain-dynamics split out of joint/collision.py,
# and the unified depth conversion in sensors.py / io/frames.py / sim/depth_sensor.py / rgbd/depth_model.py.
KNOWN_IN_FILES_BEING_REWRITTEN = {
    "tudorvision.io.frames.JointLog.at", "tudorvision.io.frames.MonoFrame", "tudorvision.io.frames.StereoFrame",
    "tudorvision.joint.adapter.AdapterStats", "tudorvision.joint.adapter.JointAdapter.encode",
    "tudorvision.joint.adapter.JointAdapter.poll", "tudorvision.joint.adapter.JointAdapter.release",
    "tudorvision.joint.adapter.JointAdapter.reply_for", "tudorvision.joint.adapter.JointAdapter.request_state",
    "tudorvision.joint.adapter.JointAdapter.reset_fault", "tudorvision.joint.adapter.JointAdapter.send_setpoint",
    "tudorvision.joint.adapter.JointAdapter.send_velocity", "tudorvision.joint.adapter.JointAdapter.set_mode",
    "tudorvision.joint.adapter.JointAdapter.set_payload", "tudorvision.joint.adapter.JointAdapter.stats",
    "tudorvision.joint.adapter.JointAdapter.wait_settled", "tudorvision.joint.proxy.FaultModel",
    "tudorvision.joint.proxy.LossyUdpProxy.start", "tudorvision.joint.proxy.LossyUdpProxy.stats",
    "tudorvision.joint.proxy.LossyUdpProxy.stop", "tudorvision.joint.proxy.LossyUdpProxy.wait_idle",
    "tudorvision.joint.safety.SafetyLimits.from_params", "tudorvision.joint.safety.SafetyPolicy",
    "tudorvision.joint.server.JointLayerServer", "tudorvision.joint.server.JointLayerServer.command_log",
    "tudorvision.joint.server.JointLayerServer.events", "tudorvision.joint.server.JointLayerServer.poll",
    "tudorvision.joint.server.JointLayerServer.run_for", "tudorvision.joint.server.JointLayerServer.serve_forever",
    "tudorvision.joint.server.JointLayerServer.shutdown", "tudorvision.joint.server.JointLayerServer.start",
    "tudorvision.joint.server.JointLayerServer.state", "tudorvision.joint.server.JointLayerServer.tick",
    "tudorvision.joint.server.JointLayerServer.tick_stats",
    "tudorvision.joint.transport.InProcessTransport",
    "tudorvision.joint.transport.InProcessTransport.close", "tudorvision.joint.transport.InProcessTransport.pair",
    "tudorvision.joint.transport.InProcessTransport.recv", "tudorvision.joint.transport.InProcessTransport.send",
    "tudorvision.joint.transport.LockstepClientTransport.close",
    "tudorvision.joint.transport.LockstepClientTransport.recv",
    "tudorvision.joint.transport.LockstepClientTransport.send", "tudorvision.joint.transport.Transport.recv",
    "tudorvision.joint.transport.Transport.send", "tudorvision.joint.transport.UdpTransport",
    "tudorvision.joint.transport.UdpTransport.client", "tudorvision.joint.transport.UdpTransport.close",
    "tudorvision.joint.transport.UdpTransport.fileno", "tudorvision.joint.transport.UdpTransport.recv",
    "tudorvision.joint.transport.UdpTransport.send", "tudorvision.joint.transport.UdpTransport.server",
}
# (b) Not yet documented (issue 13's docstring pass got through robot, geometry and servo first).
KNOWN_NOT_YET_DOCUMENTED: set = set()
KNOWN_UNDOCUMENTED = KNOWN_IN_FILES_BEING_REWRITTEN | KNOWN_NOT_YET_DOCUMENTED

# Modules allowed to switch the matplotlib backend: none.
KNOWN_MATPLOTLIB_GLOBAL_STATE: set = set()


def _is_protocol(cls) -> bool:
    return Protocol in getattr(cls, "__mro__", ()) or getattr(cls, "_is_protocol", False)


def _exported():
    """Yield ``(qualified name, object, owning class or None)`` for every checked object."""
    seen = set()
    for modname in MODULES:
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as exc:
            if exc.name == modname:
                continue
            raise
        for name in getattr(mod, "__all__", ()):
            obj = getattr(mod, name)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            qual = f"{obj.__module__}.{obj.__qualname__}"
            if qual in seen:
                continue
            seen.add(qual)
            yield qual, obj, None
            if inspect.isclass(obj):
                for attr, raw in vars(obj).items():
                    if attr.startswith("_"):
                        continue
                    if isinstance(raw, (staticmethod, classmethod)):
                        raw = raw.__func__
                    if inspect.isfunction(raw) and raw.__qualname__.startswith(obj.__qualname__ + "."):
                        yield f"{qual}.{attr}", raw, obj


def _section_names(doc, section: str) -> set[str]:
    names = set()
    for param in doc[section]:
        for part in param.name.replace("\\", "").split(","):
            if part.strip():
                names.add(part.strip())
    return names


def _class_errors(cls) -> list[tuple[str, str]]:
    """Errors for a class docstring: the numpydoc codes, with fields allowed under Attributes."""
    from numpydoc.docscrape import ClassDoc

    result = numpydoc_validate.validate(f"{cls.__module__}.{cls.__qualname__}")
    errors = [(c, m) for c, m in result["errors"] if c in CHECKED and c not in ("PR01", "PR02")]
    if any(c == "GL08" for c, _ in errors) or issubclass(cls, (enum.Enum, BaseException)):
        return errors
    doc = ClassDoc(cls, config={"show_class_members": False})
    documented = (_section_names(doc, "Parameters") | _section_names(doc, "Other Parameters")
                  | _section_names(doc, "Attributes"))
    if _is_protocol(cls):
        fields = [n for n in getattr(cls, "__annotations__", {}) if not n.startswith("_")]
    elif dataclasses.is_dataclass(cls):
        fields = [f.name for f in dataclasses.fields(cls) if f.init]
    elif issubclass(cls, tuple) and hasattr(cls, "_fields"):
        fields = list(cls._fields)
    else:
        try:
            sig = inspect.signature(cls)
        except (TypeError, ValueError):
            sig = None
        init_is_python = any(inspect.isfunction(vars(k).get("__init__")) or inspect.isfunction(vars(k).get("__new__"))
                             for k in cls.__mro__ if k is not object and k.__module__.startswith("tudorvision"))
        fields = [] if sig is None or not init_is_python else [
            p.name if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) else
            ("*" if p.kind == p.VAR_POSITIONAL else "**") + p.name
            for p in sig.parameters.values()]
        extra = _section_names(doc, "Parameters") - set(fields) - {f.lstrip("*") for f in fields}
        if extra and fields:
            errors.append(("PR02", f"Unknown parameters {sorted(extra)}"))
    missing = [f for f in fields if f not in documented and f.lstrip("*") not in documented]
    if missing:
        errors.append(("PR01", f"Parameters/fields {missing} not documented"))
    return errors


def _errors(qual, obj, owner) -> list[tuple[str, str]]:
    if inspect.isclass(obj):
        return _class_errors(obj)
    result = numpydoc_validate.validate(qual)
    return [(c, m) for c, m in result["errors"] if c in CHECKED]


def _all_problems() -> dict[str, list[tuple[str, str]]]:
    return {qual: errs for qual, obj, owner in _exported() if (errs := _errors(qual, obj, owner))}


@pytest.mark.filterwarnings("ignore::UserWarning")   # numpydoc on section underlines
def test_exported_names_have_numpydoc_sections():
    problems = _all_problems()
    failing = {q: e for q, e in problems.items() if q not in KNOWN_UNDOCUMENTED}
    lines = [f"{q}: {code} {msg}" for q, errs in sorted(failing.items()) for code, msg in errs]
    assert not lines, f"{len(failing)} public objects with docstring errors:\n" + "\n".join(lines)


@pytest.mark.filterwarnings("ignore::UserWarning")   # numpydoc on section underlines
def test_known_undocumented_list_only_shrinks():
    problems = _all_problems()
    fixed = sorted(KNOWN_UNDOCUMENTED - set(problems))
    assert not fixed, "now documented (or renamed, or no longer exported), remove from the known lists: " \
        + ", ".join(fixed)


def test_the_validator_catches_a_missing_parameter():
    def undocumented(x, y):
        """Add two numbers.

        Parameters
        ----------
        x : float
            First.
        """
        return x + y

    codes = {c for c, _ in numpydoc_validate.validate(
        numpydoc_validate.get_doc_object(undocumented))["errors"]}
    assert {"PR01", "RT01"} <= codes


# ----------------------------------------------------------------------------- matplotlib global state
def _matplotlib_global_state(tree: ast.AST) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, f"import {a.name}") for a in node.names if a.name.startswith("matplotlib.pyplot")]
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if mod.startswith("matplotlib.pyplot") or (mod == "matplotlib" and any(a.name == "pyplot"
                                                                                    for a in node.names)):
                found.append((node.lineno, f"from {mod} import ..."))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "use" \
                and isinstance(node.func.value, ast.Name) and node.func.value.id in ("matplotlib", "mpl"):
            found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_the_matplotlib_check_catches_pyplot():
    tree = ast.parse("import matplotlib\nmatplotlib.use('Agg')\nimport matplotlib.pyplot as plt\n"
                     "from matplotlib import pyplot\n")
    assert sorted(line for line, _ in _matplotlib_global_state(tree)) == [2, 3, 4]
    assert _matplotlib_global_state(ast.parse("from matplotlib.figure import Figure\n")) == []


def test_no_module_touches_the_global_matplotlib_state():
    problems, known = [], set()
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        found = _matplotlib_global_state(ast.parse(path.read_text(), filename=str(path)))
        if rel in KNOWN_MATPLOTLIB_GLOBAL_STATE:
            known |= {rel} if found else set()
            continue
        problems += [f"{rel}:{line}: {what}" for line, what in found]
    assert not problems, "use matplotlib.figure.Figure instead:\n" + "\n".join(problems)
    fixed = KNOWN_MATPLOTLIB_GLOBAL_STATE - known
    assert not fixed, "no longer touch the global state, remove from KNOWN_MATPLOTLIB_GLOBAL_STATE: " + ", ".join(fixed)
