COMMANDS = {
    "record": ("tools.replay.record_cli", "record perception streams from Zenoh into an MCAP file"),
    "replay": ("tools.replay.replay_cli", "publish an MCAP recording or a ROS 1/2 bag with its timing"),
    "inspect": ("tools.replay.inspect_cli", "summarise an MCAP recording or a ROS bag: streams, counts, rates, times"),
    "export-foxglove": ("tools.replay.export_foxglove_cli", "convert a recording to MCAP in Foxglove's well-known schemas"),
}
