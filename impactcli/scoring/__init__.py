"""The parts of :mod:`impactcli.evaluate`: detection quality against ground-truth labels,
and the equal-false-alarm threshold sweep.

Import the public names from :mod:`impactcli.evaluate`; these modules are where they live,
one concern each, and data flows one way:

- :mod:`.match`: the vocabulary every later stage shares — the matching window
  (:class:`~.match.MatchTolerance`), the events evaluation reads, the product's alarms;
- :mod:`.incidents`: the incidents (the audit's answer: link, force, contact type) scored
  against the labels;
- :mod:`.evaluation`: a log's events scored against its labels, per contact and per
  detector (:func:`~.evaluation.evaluate_events`), incidents included;
- :mod:`.sweep`: every threshold rescaled, events re-extracted and scored again;
- :mod:`.verdict`: what a sweep says — the zero-false-alarm points, adaptive against
  static_loading there, one sentence — and the sweep as JSON and text;
- :mod:`.text`: the plain-text table of an evaluation (formatting only).

Pure logic: no file I/O, no printing. The CLI (``impactcli evaluate``) reads the files.
"""



