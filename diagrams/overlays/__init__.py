"""Meshcat overlays: what the systems sense, estimate or plan, under the path `/overlays/`.

The builders only: one per task (`Add...Overlays`) wires the overlay LeafSystems of
guidedarm.systems.visualization to a station and the task's systems and aims the camera.
Each overlay system reads ordinary output ports (joint positions, ToF readings, the
follower's step record, the panel estimate) and draws on a Meshcat both live and, when the
Meshcat records (RunContext.start_recording), into the replay at the simulated time of
each publish.
"""
