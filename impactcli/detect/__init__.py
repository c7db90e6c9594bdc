"""Detection: RLS kernel, adaptive evaluator (eq. 24–42), static detectors, events,
warm-up and threshold calibration. Pure numerics: nothing here opens a file or prints."""
