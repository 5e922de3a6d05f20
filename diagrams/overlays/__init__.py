"""Meshcat overlays: what the systems sense, estimate or plan, under the path `/overlays/`.

Each overlay LeafSystem reads ordinary output ports (joint positions, ToF readings, the
follower's step record, the panel estimate) and draws on a Meshcat both live and, when the
Meshcat records (RunContext.start_recording), into the replay at the simulated time of
each publish. One builder per task (`Add...Overlays`) wires them and aims the camera.
"""
