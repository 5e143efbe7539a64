COMMANDS = {
    "record": ("services.replay.record_cli", "record perception streams from Zenoh into an MCAP file"),
    "replay": ("services.replay.replay_cli", "publish an MCAP recording or a ROS 1/2 bag with its timing"),
    "inspect": ("services.replay.inspect_cli", "summarise an MCAP recording or a ROS bag: streams, counts, rates, times"),
}
