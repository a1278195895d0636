"""One study, a linear and a nonlinear plant alike: the current word length first, then the rest, as the dashboard
draws it; cancelled once the answer is known."""

from qsid_core import CancelToken, KoopmanConfig, Study, SweepConfig

configs = {
    "dc-motor (linear)": SweepConfig(system="dc-motor", bits=(3, 5, 8, 12), realizations=3, trajectories=20, steps=200),
    "van-der-pol (nonlinear)": KoopmanConfig(system="van-der-pol", bits=(3, 5, 8), realizations=2, steps=60),
}
for name, cfg in configs.items():
    study = Study(cfg)
    print(f"{name}: a {study.kind} study")
    for frame in study.frames(bits=5):
        row = frame.rows["ls"][5]
        print(
            f"  {frame.stage:8s} {frame.done}/{frame.total} word lengths; at b = 5 the LS error of A is {row['err_A']['mean']:.4f}"
        )

# stop a study as soon as what you wanted is known (the dashboard cancels when a newer setting arrives)
token = CancelToken()
frames = Study(configs["dc-motor (linear)"]).frames(bits=12, cancel=token, chunk=1)
first = next(frames)
token.cancel()
print(f"cancelled after the {first.stage!r} frame: {sum(1 for _ in frames)} more frame(s), complete: {first.complete}")
