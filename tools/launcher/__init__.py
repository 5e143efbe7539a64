"""``perception launch``: run routers and services from a launch file as supervised child processes."""
