"""The build pipeline: the one ordered analysis, the measurement stage and its cache, layer analysis,
the fix loop, the JSON document and the orchestration of every writer."""
