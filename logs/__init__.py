"""Base layer of the rover stack: clocks, the topic registry and its schemas, message sinks, settings
readers, MCAP recording and reading, Zenoh telemetry, and trial metrics. Imports nothing of ours."""
