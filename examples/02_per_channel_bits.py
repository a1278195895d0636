"""4-bit sensors and exact actuator commands: the inputs' quantization no longer spoils B."""

from qsid_core import SweepConfig, run_sweep

for input_bits in (None, 12, "exact"):
    res = run_sweep(
        SweepConfig(
            system="boeing747", bits=(4,), input_bits=input_bits, realizations=5, trajectories=50, steps=400, mpc=None
        )
    )
    row = res.summary(4).to_dict()
    print(
        f"input bits {str(input_bits or 'same as b'):>9}: eps_u {[round(e, 4) for e in row['eps_u']]}, "
        f"err_B {row['err_B']['mean']:.3e}"
    )
