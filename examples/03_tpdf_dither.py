"""Dither without a shared generator at the receiver: TPDF keeps BCLS working, RPDF does not."""

from qsid_core import QuantizerSpec, SweepConfig, run_sweep

for dither in ("subtractive", "tpdf", "rpdf"):
    q = QuantizerSpec(dither=dither, range_mode="fixed", fixed_range=(-20, 20))
    res = {
        est: run_sweep(
            SweepConfig(
                system="boeing747",
                bits=(3,),
                quantizer=q,
                estimator=est,
                realizations=2,
                trajectories=100,
                steps=500,
                mpc=None,
            )
        )
        for est in ("ls", "bcls")
    }
    d = res["bcls"].to_dict()["bcls"]
    print(
        f"{dither:11s} LS {res['ls'].summary(3).err_A.mean:.3f}  BCLS {res['bcls'].summary(3).err_A.mean:.3f}  "
        f"BCLS applicable: {d['applicable']} (D = {d['D']})"
    )
