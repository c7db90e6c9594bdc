"""CSV logs: canonical wide CSV, or any CSV through a channel map — what a file's first lines
say (:mod:`~impactcli.logs.csv.csv_header`, :mod:`~impactcli.logs.csv.csv_layout`), the
reader (:mod:`~impactcli.logs.csv.csv_read`) and its exact passes
(:mod:`~impactcli.logs.csv.csv_exact`). Opened through :func:`impactcli.logs.open_log`."""
