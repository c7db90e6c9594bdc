"""The replay of a log: plan it, replay it chunk by chunk, apply the thresholds, build the
result (:func:`impactcli.run.one_log.detect_log`), and feed the writers a verb asked for
(:func:`impactcli.run.job.run_log`)."""
