"""dynamic_reconfigure values -> the finders' config dataclasses: pure functions, no ROS.

A node's reconfigure callback gets a dict of every parameter of its .cfg file (cfg/*.cfg). Names
are the config dataclasses' field names; the automatic search's fields that clash with the
operator steps' (r_eps, refine_iterations) carry an ``auto_`` prefix; the cylinder search's fields
that are parameters (AutoConfig.cylinders' ``lying_*`` and ``projector_offset``) take their own
names. Unknown names are ignored.
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
    auto, cylinder_changes = _with_cylinders(auto, values)
    operator_values = {k: v for k, v in values.items() if not k.startswith(AUTO_PREFIX)}
    updated, changes = replace_fields(dataclasses.replace(finder, auto=auto), operator_values)
    updated.validate()
    updated.auto.validate()
    updated.auto.cylinders.validate()
    log = [f"{k} {old} -> {new}" for k, (old, new) in changes.items()]
    log += [f"{AUTO_PREFIX if k in shared else ''}{k} {old} -> {new}" for k, (old, new) in auto_changes.items()]
    log += [f"{k} {old} -> {new}" for k, (old, new) in cylinder_changes.items()]
    return updated, log


def param_names(finder):
    """Every name finder_from_values takes for a FinderConfig: the operator steps' scalar fields,
    then the automatic search's (``auto_``-prefixed where the names clash)."""
    operator = _scalar_names(finder)
    return (operator + [AUTO_PREFIX + n if n in operator else n for n in _scalar_names(finder.auto)]
            + _cylinder_names(finder.auto))


LYING_PREFIX = "lying_"
# The cylinder search's other fields that are parameters (cfg/can_search_params.py, group sensor).
SENSOR_NAMES = ("projector_offset",)


def _cylinder_names(auto):
    """The names of an AutoConfig's CylinderSearchConfig fields that are parameters: the lying step's
    (lying_*) and the sensor's."""
    return [n for n in _scalar_names(auto.cylinders) if n.startswith(LYING_PREFIX) or n in SENSOR_NAMES]


def _with_cylinders(auto, values):
    """(AutoConfig with its cylinder search's parameter fields set from values, {field: (old, new)})."""
    cylinders, changes = replace_fields(auto.cylinders, {k: values[k] for k in _cylinder_names(auto) if k in values})
    return dataclasses.replace(auto, cylinders=cylinders), changes


LOCAL_PREFIX = "local_"


def _scalar_names(config):
    """The names of config's fields that are single values (no tuples, lists, None or nested configs)."""
    return [f.name for f in dataclasses.fields(config)
            if not isinstance(getattr(config, f.name), (tuple, list)) and getattr(config, f.name) is not None
            and not dataclasses.is_dataclass(getattr(config, f.name))]


def tracker_from_values(local, tracker, values):
    """can_tracker's LocalFitConfig (with its .auto AutoConfig) and TrackerConfig updated from
    reconfigure `values` (cfg/CanTracker.cfg).

    The search's fields take the names of cfg/can_search_params.py (``auto_`` + the name where
    find_can's operator steps use it; its cylinder search's, lying_* and projector_offset, their
    own); the local refit's take theirs, or ``local_`` + the name where the search uses it too
    (max_fit_points, fit_tolerance); the tracker's take theirs.
    Returns (LocalFitConfig, TrackerConfig, changes: "name old -> new" strings for the log).
    Raises PerceptionError (nothing changed) when a result would not validate.
    """
    auto_names = set(_scalar_names(local.auto))
    auto, auto_changes = replace_fields(local.auto, {k: v for k, v in values.items()
                                                     if not k.startswith(LOCAL_PREFIX)}, AUTO_PREFIX)
    auto, cylinder_changes = _with_cylinders(auto, values)
    local_values = {k: v for k, v in values.items() if k.startswith(LOCAL_PREFIX) or k not in auto_names}
    updated_local, local_changes = replace_fields(dataclasses.replace(local, auto=auto), local_values, LOCAL_PREFIX)
    updated_tracker, tracker_changes = replace_fields(
        tracker, {k: v for k, v in values.items() if k not in auto_names and not k.startswith(LOCAL_PREFIX)})
    updated_local.validate()
    updated_local.auto.cylinders.validate()
    updated_tracker.validate()
    log = [f"{AUTO_PREFIX if AUTO_PREFIX + k in values else ''}{k} {old} -> {new}"
           for k, (old, new) in auto_changes.items()]
    log += [f"{k} {old} -> {new}" for k, (old, new) in cylinder_changes.items()]
    log += [f"{LOCAL_PREFIX if k in auto_names else ''}{k} {old} -> {new}" for k, (old, new) in local_changes.items()]
    log += [f"{k} {old} -> {new}" for k, (old, new) in tracker_changes.items()]
    return updated_local, updated_tracker, log


def tracker_param_names(local, tracker):
    """Every name tracker_from_values takes: the search's (as cfg/can_search_params.py names
    them: ``auto_`` where find_can's operator steps have the name), the local refit's (``local_``-prefixed
    where the search has the name) and the tracker's."""
    from example_pcl.can_finder import FinderConfig

    auto = [n for n in param_names(FinderConfig()) if n not in _scalar_names(FinderConfig())]
    auto_names = set(_scalar_names(local.auto))
    return (auto + [LOCAL_PREFIX + n if n in auto_names else n for n in _scalar_names(local)]
            + _scalar_names(tracker))
