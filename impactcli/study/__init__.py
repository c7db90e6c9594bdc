"""The sensitivity study (``impactcli sensitivity``): the paper's Table II on the simulator,
a false-alarm soak, the detectors compared at matched false-alarm rates. Its design:
docs/validation.md. Modules, data flowing one way:

- :mod:`.spec`: what the study runs — the paper's numbers, the variants, :class:`~.spec.StudySpec`;
- :mod:`.scenarios`: the one simulated robot, the task's amplitudes, references and scenarios;
- :mod:`.tasks`: the calibration, soak and case tasks (top-level: they run in worker processes);
- :mod:`.summary`: the outcomes summarised into one JSON-ready mapping, verdicts included;
- :mod:`.tables`: that mapping as Table II, the ROC table and the verdicts, in text and Markdown;
- :mod:`.runner`: :func:`~.runner.run_study` runs the tasks and summarises them.
"""
