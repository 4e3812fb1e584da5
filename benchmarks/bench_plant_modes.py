"""Issue 18: the lab's figure 4.8 — first-mode frequency and decay over (theta2, theta3) at 300 g — beside the seed.

For every grid pose the seed-measured default plant (``PlantConfig()``)
is hit by the hammer impulse at the end effector while the joint cascade
holds the pose (``tudorvision.lab.plant_modes.ring_down``); the first
dominant frequency is the spectral peak of the link-2 hub strain and the
decay rate its envelope fit, as the seed's figure 4.8 (strain on link 2,
B.3.26). The linearised first frequency (joints held, springs engaged) and
the stiff plant ``PlantConfig.stiff()`` (one-way BVP, and two-way rigid hubs) are listed for
comparison. The peer is the seed: its ranges (1.56-2.74 Hz, 0.03-1.24 1/s)
and figure 4.6 (2.0 / 9.9 Hz link 2, 6.3 Hz link 3); ratios lab / seed are printed.

Usage::

    nice .venv/bin/python benchmarks/bench_plant_modes.py --step 20 --png docs/figures/plant_modes_map.png
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from tudorvision.lab.plant_modes import identify_hub_stiffness, linear_modes, modes_map, plate_payload
from tudorvision.sim.arm import ElasticArm, PlantConfig

SEED = {"f1_range_hz": (1.56, 2.74), "decay_range_per_s": (0.03, 1.24), "link2_hz": (2.0, 9.9), "link3_hz": 6.3}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=20.0, help="grid step, degrees (seed: 10)")
    ap.add_argument("--payload-kg", type=float, default=0.3)
    ap.add_argument("--duration", type=float, default=6.0, help="ring-down seconds per pose")
    ap.add_argument("--png", help="write the two maps as a PNG")
    ap.add_argument("--json", help="write the grid numbers as JSON")
    ap.add_argument("--servo", metavar="T_D,T_L", help="time constants of the holding cascade, s "
                    "(default the joint layer's loop for the plant, joint.damping_gains.HOLD_LOOPS)")
    ap.add_argument("--identify", action="store_true",
                    help="only the linearised grid search of the hub stiffnesses (identify_hub_stiffness)")
    a = ap.parse_args(argv)
    if a.identify:
        best, table = identify_hub_stiffness()
        print("K_r2 K_r3 [N m/rad] | link2 f1 f2, link3 f1 at theta=0 | max f1 over theta3 | worst rel. error")
        for row in sorted(table, key=lambda r: r[-1]):
            print(f"{row[0]:6g} {row[1]:6g} | {row[2]:.3f} {row[3]:.3f} {row[4]:.3f} | {row[5]:.3f} | {row[6]:.3f}")
        print(f"best {best}")
        return 0
    cfg = PlantConfig()                   # the seed-measured default
    t0 = time.perf_counter()
    servo = tuple(float(x) for x in a.servo.split(",")) if a.servo else None
    m = modes_map(a.step, a.payload_kg, cfg, a.duration, servo_time_constants_s=servo)
    wall = time.perf_counter() - t0
    t2s, t3s = np.array(m["theta2_deg"]), np.array(m["theta3_deg"])
    F, Z, FL = np.array(m["ringdown_hz"]), np.array(m["decay_per_s"]), np.array(m["linear_hz"])
    fig46 = linear_modes(np.deg2rad([0.0, 0.0, 0.0]), a.payload_kg, cfg)
    stiff_one_way = ElasticArm(np.deg2rad([0.0, 0.0, 0.0]), config=PlantConfig.stiff(),
                               payload=plate_payload(a.payload_kg)).link2.basis.frequency_hz
    stiff2 = [linear_modes(np.deg2rad([0.0, 0.0, t3]), a.payload_kg, PlantConfig.stiff(two_way=True))["link2_hz"][0]
              for t3 in t3s]

    def row(name, lab, seed):
        print(f"{name:42s} lab {lab:7.3f}   seed {seed:6.2f}   lab/seed {lab / seed:5.2f}")

    print("holding cascade (t_d, t_l):", servo or "the joint layer's loop for the plant (HOLD_LOOPS)")
    print(f"grid {len(t2s)} x {len(t3s)} poses (step {a.step:g} deg), payload {a.payload_kg} kg, "
          f"{a.duration:g} s ring-downs, {wall:.0f} s wall ({wall / F.size:.2f} s per pose)")
    row("fig 4.6 link 2 first (theta=0,0,0), Hz", fig46["link2_hz"][0], SEED["link2_hz"][0])
    row("fig 4.6 link 2 second, Hz", fig46["link2_hz"][1], SEED["link2_hz"][1])
    row("fig 4.6 link 3 first, Hz", fig46["link3_hz"][0], SEED["link3_hz"])
    row("fig 4.8 first frequency min (ring-down), Hz", F.min(), SEED["f1_range_hz"][0])
    row("fig 4.8 first frequency max (ring-down), Hz", F.max(), SEED["f1_range_hz"][1])
    row("fig 4.8 decay min, 1/s", Z.min(), SEED["decay_range_per_s"][0])
    row("fig 4.8 decay max, 1/s", Z.max(), SEED["decay_range_per_s"][1])
    print(f"linearised first frequency over the grid: {FL.min():.3f} .. {FL.max():.3f} Hz")
    print(f"stiff plant: one-way BVP {stiff_one_way[0]:.3f} / {stiff_one_way[1]:.3f} Hz at every pose; "
          f"two-way rigid hubs {min(stiff2):.3f} .. {max(stiff2):.3f} Hz")
    lo = np.unravel_index(np.argmin(F), F.shape)
    print(f"lowest ring-down frequency at theta2={t2s[lo[1]]:g}, theta3={t3s[lo[0]]:g} deg; "
          f"largest decay at theta2={t2s[np.unravel_index(np.argmax(Z), Z.shape)[1]]:g}, "
          f"theta3={t3s[np.unravel_index(np.argmax(Z), Z.shape)[0]]:g} deg")
    if a.json:
        from tudorvision.io.atomic import write_text_atomic
        write_text_atomic(a.json, json.dumps({"theta2_deg": t2s.tolist(), "theta3_deg": t3s.tolist(),
                                              "ringdown_hz": F.tolist(), "decay_per_s": Z.tolist(),
                                              "linear_hz": FL.tolist()}) + "\n")
    if a.png:
        from matplotlib.figure import Figure
        from tudorvision.io.atomic import atomic_path
        fig = Figure(figsize=(8.0, 3.0))
        ax = fig.subplots(1, 2)
        ext = [t2s[0] - a.step / 2, t2s[-1] + a.step / 2, t3s[0] - a.step / 2, t3s[-1] + a.step / 2]
        for k, (M, title) in enumerate(((F, "first frequency [Hz]"), (Z, "decay rate ζ₁ [1/s]"))):
            im = ax[k].imshow(M, origin="lower", extent=ext, aspect="auto", cmap="viridis")
            ax[k].plot(t2s, 90 - t2s, "w--", lw=0.8)
            ax[k].axvline(90, color="w", ls=":", lw=0.8)
            ax[k].set_xlim(ext[0], ext[1]); ax[k].set_ylim(ext[2], ext[3])
            ax[k].set_xlabel("θ2 [deg]"); ax[k].set_ylabel("θ3 [deg]"); ax[k].set_title(title, fontsize=9)
            fig.colorbar(im, ax=ax[k])
        fig.tight_layout()
        with atomic_path(a.png) as tmp:
            fig.savefig(tmp, dpi=80, format="png")
        print(f"wrote {a.png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
