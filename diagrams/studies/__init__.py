"""Studies of many runs behind the command line's study commands: planner_comparison
(`guidedarm compare-planners`: the acceleration-level planner against the paper's law,
movej, Toppra and Ruckig) and marker_study (`guidedarm marker-study`: the accuracy tables
of Annusewicz-Mistal et al. from their campaigns)."""
