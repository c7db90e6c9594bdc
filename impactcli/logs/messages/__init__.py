"""Message logs: MCAP files (:mod:`~impactcli.logs.messages.mcap`) and ROS bags
(:mod:`~impactcli.logs.messages.bags`) seen the same way
(:mod:`~impactcli.logs.messages.message_source`), ROS 2 CDR decoding
(:mod:`~impactcli.logs.messages.ros2_cdr`), message fields named PlotJuggler-style
(:mod:`~impactcli.logs.messages.fields`, :mod:`~impactcli.logs.messages.field_read`), and
the one reader (:mod:`~impactcli.logs.messages.message_read`: its plan and its merge of the
topics into rows, :mod:`~impactcli.logs.messages.message_plan`,
:mod:`~impactcli.logs.messages.message_merge`). Opened through
:func:`impactcli.logs.open_log`."""
