"""The run: the plan of a test matrix, the engine that executes it, interlock supervision and the rig's I/O."""
