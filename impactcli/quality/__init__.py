"""Detection quality against ground-truth labels, and the equal-false-alarm threshold sweep,
one concern a module, data flowing one way (each imports only the ones before it):

- :mod:`.match`: the vocabulary every later stage shares — the matching window
  (:class:`~.match.MatchTolerance`), the events evaluation reads, the product's alarms;
- :mod:`.incidents`: the incidents (the audit's answer: link, force, contact type) scored
  against the labels;
- :mod:`.evaluation`: a log's events scored against its labels, per contact and per
  detector (:func:`~.evaluation.evaluate_events`), incidents included;
- :mod:`.sweep`: every threshold rescaled, events re-extracted and scored again, fed by
  chunks (:class:`~.sweep.ThresholdSweep`);
- :mod:`.verdict`: what a sweep says — the zero-false-alarm points, adaptive against
  static_loading there, one sentence — and the sweep as JSON and text;
- :mod:`.text`: the plain-text table of an evaluation (formatting only).

Pure logic: no file I/O, no printing. The CLI (``impactcli evaluate``) reads the files.
"""
