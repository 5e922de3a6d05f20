"""The compiled kernels (plain C against Python's C API, no other headers), built by
`pip install -e .` (`make .venv/.installed`); everything else is in pyproject.toml."""

from setuptools import Extension, setup

# -ffp-contract=off: no fused multiply-adds, so the kernels round as the numpy references
# they are tested against do.
FLAGS = ["-O2", "-ffp-contract=off"]

setup(
    ext_modules=[
        Extension(
            "guidedarm.systems.path_following._servo_step",
            ["csrc/servo_step.c"],
            depends=["csrc/buffers.h"],
            extra_compile_args=FLAGS,
        ),
        Extension(
            "guidedarm.systems.tof._hose_range",
            ["csrc/hose_range.c", "csrc/hose_range_model.c"],
            depends=["csrc/buffers.h", "csrc/hose_range.h"],
            extra_compile_args=FLAGS,
        ),
        Extension(
            "guidedarm.systems.tof._seed_sequence",
            ["csrc/seed_sequence.c"],
            extra_compile_args=FLAGS,
        ),
        Extension(
            "guidedarm.systems.tof._cone_casting",
            ["csrc/cone_casting.c"],
            depends=["csrc/buffers.h"],
            extra_compile_args=FLAGS,
        ),
    ]
)
