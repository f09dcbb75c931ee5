"""The commands' application layer: what ``ipromp-pin run``, ``replay``, ``preview``, ``evaluate``
and ``calibrate`` do, from a typed configuration to written files.

- :mod:`.config`: pipeline definitions (TOML): typed sections, one source of each default,
  validated once at the boundary.
- :mod:`.setup`: the one set-up of ``run``, ``replay`` and ``preview`` (``prepare_session`` ->
  ``Session``: robot, data, held-out demo, model, warnings, mesh prefetch), built once per command.
- :mod:`.run`, :mod:`.replay`, :mod:`.preview`, :mod:`.evaluate`, :mod:`.calibrate`: one command
  each; none imports another's module.
- :mod:`.model_cache`: trained models reused across runs on the same demos and settings;
  :mod:`.model_warnings`: one-line warnings where a user is likely to be fooled; :mod:`.meshes`:
  the preview meshes decimated while the model trains.

The command line (:mod:`ipromp_pin.cli`) parses arguments into these; nothing here parses them.
"""
