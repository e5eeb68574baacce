"""Reference tables generated from the code at build time, so the manual cannot drift from it.

Directives (usable from MyST as ```{model-fields} ...```):

- `model-fields MODULE:CLASS`: a table of a pydantic file schema's keys (type and constraints, default or
  "required", the comment the source gives the field), then one table per nested schema it uses.
- `exit-statuses`: `rov-mav run`'s exit statuses, their numbers read from the constants the runner returns.
- `runlog-columns`: ticks.csv's columns, from `rov_mav.flight.record.runlog.COLUMNS`; a column this file does not
  describe
  fails the build (a new column needs a line here).
- `fault-grammar vehicle|link`: the keys of `--vehicle-faults` / `--link-faults` from their parsers' modules.
"""

from __future__ import annotations

import importlib
import inspect
import re
import types
import typing

from docutils import nodes
from docutils.parsers.rst import Directive, directives
from pydantic import BaseModel
from sphinx.util import logging

LOG = logging.getLogger(__name__)


# -- the command reference ---------------------------------------------------------------------------------------

def cli_parser():
    """`rov_mav.cli.build_parser()`, the parser `rov-mav` runs, every subcommand's arguments added, with the help
    texts made literal for reStructuredText (sphinx-argparse parses them as such: `|velocity|` would be a substitution,
    a lone `*` an emphasis). Option names, choices and defaults are untouched."""
    import argparse
    from rov_mav.cli import build_parser

    def plain(text):
        return re.sub(r"([|*`_\\])", r"\\\1", text) if isinstance(text, str) else text

    def walk(parser):
        parser.description, parser.epilog = plain(parser.description), plain(parser.epilog)
        for group in parser._action_groups:
            group.description = plain(group.description)
        for action in parser._actions:
            action.help = plain(action.help)
            if isinstance(action, argparse._SubParsersAction):
                for choice in action._choices_actions:
                    choice.help = plain(choice.help)
                for sub in action.choices.values():
                    walk(sub)

    parser = build_parser()
    walk(parser)
    return parser


# -- a docutils table from rows of cells; a cell is text, with `code` spans as literals -------------------------

def _cell(text: str) -> nodes.entry:
    para = nodes.paragraph()
    for i, part in enumerate(str(text).split("`")):
        if part:
            para += nodes.literal(part, part) if i % 2 else nodes.Text(part)
    entry = nodes.entry()
    entry += para
    return entry


def _table(header: list[str], rows: list[list[str]], widths: list[int] | None = None) -> nodes.table:
    table = nodes.table(classes=["rovmav-generated"])
    group = nodes.tgroup(cols=len(header))
    table += group
    for w in widths or [1] * len(header):
        group += nodes.colspec(colwidth=w)
    head = nodes.thead()
    group += head
    row = nodes.row()
    for h in header:
        row += _cell(h)
    head += row
    body = nodes.tbody()
    group += body
    for cells in rows:
        row = nodes.row()
        for c in cells:
            row += _cell(c)
        body += row
    return table


# -- pydantic schemas ---------------------------------------------------------------------------------------------

def _constraints(metadata) -> list[str]:
    out = []
    for m in metadata:
        for name, sign in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="),
                           ("min_length", "items >="), ("max_length", "items <=")):
            value = getattr(m, name, None)
            if value is not None:
                out.append(f"{sign} {value:g}" if isinstance(value, float) else f"{sign} {value}")
    return out


def _type_text(annotation, nested: list[type]) -> str:
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        base, *metadata = args
        text = _type_text(base, nested)
        extra = _constraints(metadata)
        for m in metadata:                      # Field(...) carries its constraints in .metadata
            extra += _constraints(getattr(m, "metadata", []))
        return f"{text} ({', '.join(extra)})" if extra else text
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_text(a, nested) for a in args)
    if origin is typing.Literal:
        return "one of " + ", ".join(f"`{a}`" for a in args)
    if origin in (list, tuple):
        return "list of " + " or ".join(_type_text(a, nested) for a in args if a is not Ellipsis)
    if origin is dict:
        return "mapping"
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        if annotation not in nested:
            nested.append(annotation)
        return f"`{_schema_name(annotation)}` block"
    return {float: "number", int: "integer", str: "text", bool: "true/false"}.get(annotation, str(annotation))


def _schema_name(cls: type) -> str:
    return re.sub(r"(Schema|File)$", "", cls.__name__.lstrip("_")).lower() or cls.__name__


def _comments(cls: type) -> dict[str, str]:
    """The trailing comment of each field's line in the class source (the schemas document their fields so)."""
    found = {}
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return found
    for line in source.splitlines():
        m = re.match(r"\s+(\w+)\s*:[^#]*#\s*(.+)$", line)
        if m:
            found[m.group(1)] = m.group(2).strip()
    return found


def _default_text(field) -> str:
    if field.is_required():
        return "required"
    if field.default_factory is not None:
        return "(built)"
    value = field.default
    if isinstance(value, BaseModel):
        return "its defaults"
    if value == "":
        return "empty"
    return "none" if value is None else f"`{value}`"


def _load(spec: str):
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


class ModelFields(Directive):
    required_arguments = 1
    option_spec = {"title": directives.unchanged, "no-nested": directives.flag}

    def run(self):
        cls = _load(self.arguments[0])
        out, nested, done = [], [cls], set()
        while nested:
            model = nested.pop(0)
            if model in done:
                continue
            done.add(model)
            comments = _comments(model)
            rows, found = [], []
            for name, field in model.model_fields.items():
                kind = _type_text(field.annotation, found)
                extra = _constraints(field.metadata)
                rows.append([f"`{name}`", f"{kind} ({', '.join(extra)})" if extra else kind, _default_text(field),
                             comments.get(name, "")])
            if model is not cls:
                out.append(nodes.paragraph(text=f"The {_schema_name(model)} block:"))
            doc = (model.__doc__ or "").strip()
            if doc and "Create a new model" not in doc:
                out.append(nodes.paragraph(text=" ".join(doc.split())))
            out.append(_table(["key", "type", "default", "meaning (from the schema's source)"], rows, [2, 4, 2, 6]))
            if "no-nested" not in self.options:
                nested.extend(found)
        return out


# -- exit statuses ------------------------------------------------------------------------------------------------

class ExitStatuses(Directive):
    def run(self):
        from rov_mav.flight.run.run_options import HANDED_OVER
        from rov_mav.flight.run.thruster_watch import EXIT_THRUSTER
        from rov_mav.flight.session.vehicle_events import EXIT_FAILSAFE, EXIT_REBOOT
        rows = [
            ["0", "the mission completed and every step of the safe stop was confirmed"],
            ["1", "aborted or refused (the reason is printed), or a step of the safe stop the vehicle never "
                  "confirmed (named in the last line)"],
            ["2", "bad arguments or files (one line naming the option, file or key); nothing ran"],
            [str(HANDED_OVER), "handed over to the pilot or another station"],
            [str(EXIT_THRUSTER), "a thruster failed and the others cannot fly the mission"],
            [str(EXIT_REBOOT), "the vehicle rebooted during the run"],
            [str(EXIT_FAILSAFE), "the vehicle's own failsafe: a leak, a critical battery, its estimator, its "
                                 "depth sensor, SURFACE"],
            ["130", "interrupted with Ctrl-C outside a run"],
            ["128+N", "stopped by signal N (130 Ctrl-C, 143 SIGTERM) after the safe stop"],
        ]
        return [_table(["status", "meaning"], rows, [1, 8])]


# -- the run log --------------------------------------------------------------------------------------------------

_COLUMN_TEXT = [   # (pattern, meaning): every column of runlog.COLUMNS must match one
    (r"t", "wall seconds since the run started"),
    (r"vehicle_time", "the vehicle's clock (time_boot_ms) in s"),
    (r"progress", "share of the mission flown, 0 to 1"),
    (r"x|y|z", "position, NED, m (the estimate the law flew on)"),
    (r"phi|theta|psi", "roll, pitch, yaw, rad"),
    (r"u|v|w", "body velocity, m/s"),
    (r"p|q|r", "body rates, rad/s"),
    (r"(x|y|z|phi|theta|psi)_d", "reference pose"),
    (r"(x|y|z|phi|theta|psi)_dot_d", "reference velocity (rate of the pose)"),
    (r"(x|y|z|phi|theta|psi)_ddot_d", "reference acceleration"),
    (r"tau_[XYZKMN]", "the commanded body wrench, N and N m"),
    (r"tau_hat_[XYZKMN]", "the wrench the law holds against the disturbance (τ̂)"),
    (r"s_\w+", "the law's sliding variable per DOF"),
    (r"gamma_\w+", "the adaptation rate per DOF (adaptive backstepping only)"),
    (r"thrust_[1-8]", "each thruster's commanded thrust, N"),
    (r"pwm_[1-8]", "each thruster's PWM, µs"),
    (r"telemetry_age", "age of the state the tick used, s"),
    (r"latency", "telemetry in to command out, s"),
    (r"control_rate", "ticks per vehicle second"),
    (r"battery_voltage", "the vehicle's battery, V"),
    (r"horizon", "how far ahead the state was predicted, s"),
    (r"(x|y|z)_true", "where a simulator says the vehicle is (empty on a real vehicle)"),
    (r"(x|y|z)_vehicle", "the vehicle's own estimate (as reported, before the run's blending)"),
    (r"height", "on an altitude or standoff leg: the echo sounder's last range taken in, m (empty elsewhere)"),
    (r"height_true", "... the true height above the bottom (below the ice), where a simulator says it, m"),
    (r"surface_depth", "... the estimated depth of the bottom (or the ice), m"),
]


class RunlogColumns(Directive):
    def run(self):
        from rov_mav.flight.record import runlog
        rows, groups = [], {}
        for column in runlog.COLUMNS:
            meaning = next((text for pattern, text in _COLUMN_TEXT if re.fullmatch(pattern, column)), None)
            if meaning is None:
                raise self.error(f"ticks.csv column {column!r} has no description in docs/_ext/rovmav_docs.py")
            groups.setdefault(meaning, []).append(column)
        for meaning, columns in groups.items():
            rows.append([", ".join(f"`{c}`" for c in columns), meaning])
        intro = nodes.paragraph(text=f"ticks.csv has {len(runlog.COLUMNS)} columns, in this order; run.json "
                                     f"({runlog.RUN_INFO}) describes the run.")
        return [intro, _table(["columns", "meaning"], rows, [4, 5])]


# -- fault descriptions ---------------------------------------------------------------------------------------------

class FaultGrammar(Directive):
    required_arguments = 1

    def run(self):
        kind = self.arguments[0]
        if kind == "vehicle":
            module = importlib.import_module("rov_mav.model.vehicle_faults")
            items = [line for line in (module.__doc__ or "").splitlines() if line.startswith("- `")]
            rows = [list(m.groups()) for m in (re.match(r"- `([^`]+)`\s+(.*)", line) for line in items) if m]
            keys = sorted({re.split(r"[=@]", r[0])[0] for r in rows})
            missing = set(module.KEYS) - set(keys)
            if missing:
                raise self.error(f"vehicle fault keys without a line in the module docstring: {sorted(missing)}")
            table = _table(["item", "what fails"], [[f"`{a}`", b] for a, b in rows], [3, 6])
        else:
            module = importlib.import_module("sim_bridge.transport.faults")
            rows = [[f"`{k}`", "probability, 0 to 1 or a percentage"] for k in module.PROBABILITIES]
            rows += [[f"`{k}`", "a time with its unit (ms or s)"] for k in module.DURATIONS]
            rows += [["`cut`", "LENGTH@START: nothing sent in between arrives"],
                     ["`drop`", "MESSAGE[@START]: that message type never arrives from START on (repeatable)"],
                     ["`link`", "N: only endpoint N (from 0, the --out ones first); default all"]]
            if {r[0].strip("`") for r in rows} != set(module.KEYS):
                raise self.error(f"link fault keys changed: {module.KEYS}")
            table = _table(["key", "value"], rows, [2, 6])
        example = nodes.paragraph()
        example += nodes.Text("Example: ")
        example += nodes.literal(module.EXAMPLE, module.EXAMPLE)
        return [table, example]


# -- module docstrings ----------------------------------------------------------------------------------------------

class ModuleDocstrings(Directive):
    """Each module of a package and its rooms with its docstring as written (the emulated ArduSub cites ArduPilot's
    source there)."""

    required_arguments = 1

    def run(self):
        import pkgutil
        package = importlib.import_module(self.arguments[0])
        out = []
        found = pkgutil.walk_packages(package.__path__, prefix=f"{package.__name__}.")
        for info in sorted((i for i in found if not i.ispkg), key=lambda i: i.name):
            module = importlib.import_module(info.name)
            doc = inspect.cleandoc(module.__doc__ or "")
            if not doc:
                continue
            title = info.name.replace(".", "/") + ".py"
            section = nodes.section(ids=[nodes.make_id(title)], names=[nodes.fully_normalize_name(title)])
            section += nodes.title(text=title)
            section += nodes.literal_block(doc, doc, classes=["rovmav-docstring"])
            out.append(section)
        return out


def setup(app):
    app.add_directive("model-fields", ModelFields)
    app.add_directive("exit-statuses", ExitStatuses)
    app.add_directive("runlog-columns", RunlogColumns)
    app.add_directive("fault-grammar", FaultGrammar)
    app.add_directive("module-docstrings", ModuleDocstrings)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
