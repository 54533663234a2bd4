"""dynamic_reconfigure values -> the finders' config dataclasses: pure functions, no ROS.

A node's reconfigure callback gets a dict of every parameter of its .cfg file (cfg/*.cfg). Names
are the config dataclasses' field names; the automatic search's fields that clash with the
operator steps' (r_eps, refine_iterations) carry an ``auto_`` prefix. Unknown names are ignored.
"""
import dataclasses

from example_pcl.errors import PerceptionError

AUTO_PREFIX = "auto_"


def replace_fields(config, values, prefix=""):
    """(copy of dataclass `config` with the scalar fields named in `values` replaced, {field: (old, new)}).

    A value named ``prefix + field`` sets ``field``; one named ``field`` does too unless ``prefix``
    is set and the unprefixed name is taken by another config (the caller passes those names in
    values only prefixed). Each value is converted to the field's current type; tuple and
    dataclass fields are never set from here.
    """
    changes = {}
    for field in dataclasses.fields(config):
        old = getattr(config, field.name)
        if isinstance(old, (tuple, list)) or dataclasses.is_dataclass(old) or old is None:
            continue
        for name in (prefix + field.name, field.name) if prefix else (field.name,):
            if name in values:
                try:
                    new = type(old)(values[name])
                except (TypeError, ValueError):
                    raise PerceptionError(f"{name} must be a {type(old).__name__}, got {values[name]!r}") from None
                if new != old:
                    changes[field.name] = (old, new)
                break
    return dataclasses.replace(config, **{k: new for k, (_, new) in changes.items()}), changes


def finder_from_values(finder, values):
    """find_can's FinderConfig (with its .auto AutoConfig) updated from reconfigure `values`.

    Returns (FinderConfig, changes: list of "name old -> new" strings for the log). The operator
    steps' fields take their own names; the automatic search's fields take theirs, or ``auto_``
    + the name where the operator steps use it too. Raises PerceptionError (nothing changed) when
    the result would not validate.
    """
    shared = {f.name for f in dataclasses.fields(finder)}
    auto_values = {k: v for k, v in values.items() if k.startswith(AUTO_PREFIX) or k not in shared}
    auto, auto_changes = replace_fields(finder.auto, auto_values, AUTO_PREFIX)
    operator_values = {k: v for k, v in values.items() if not k.startswith(AUTO_PREFIX)}
    updated, changes = replace_fields(dataclasses.replace(finder, auto=auto), operator_values)
    updated.validate()
    updated.auto.validate()
    log = [f"{k} {old} -> {new}" for k, (old, new) in changes.items()]
    log += [f"{AUTO_PREFIX if k in shared else ''}{k} {old} -> {new}" for k, (old, new) in auto_changes.items()]
    return updated, log


def param_names(finder):
    """Every name finder_from_values takes for a FinderConfig: the operator steps' scalar fields,
    then the automatic search's (``auto_``-prefixed where the names clash)."""
    def scalar(config):
        return [f.name for f in dataclasses.fields(config)
                if not isinstance(getattr(config, f.name), (tuple, list)) and getattr(config, f.name) is not None
                and not dataclasses.is_dataclass(getattr(config, f.name))]

    operator = scalar(finder)
    return operator + [AUTO_PREFIX + n if n in operator else n for n in scalar(finder.auto)]
