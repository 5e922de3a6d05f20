"""Helpers several tasks share: tracking (a measured arm against its commands),
trajectory_csv (every arm task's trajectory.csv), cell_collisions (the arm against its cell
and itself), planner_builder (MakeAccelerationPlanner for an arm of a station)."""
