"""The node runtime: the node shape and its runner, signals, counters and status, joins,
layered configuration, and what the commands share."""
