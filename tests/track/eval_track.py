#!/usr/bin/env python3
"""Per-frame MPJPE / PA-MPJPE of a `kinesplat track` output against a synth's truth.

usage: eval_track.py KINESPLAT TRACK SYNTH_TRAIN_DIR
Each frame's fit (pass 2, shared shape) and its independent fit (pass 1) are written as fit.json
files and compared with the synth frame's true pose and camera by `kinesplat evaluate-fit`; the
kept frames' indices select the dataset frames. Prints a JSON summary (medians, per frame)."""
import json, os, statistics, subprocess, sys, tempfile

kinesplat, track_dir, train = sys.argv[1:4]
track = json.load(open(os.path.join(track_dir, "track.json")))
ds = json.load(open(os.path.join(train, "dataset.json")))
tmp = tempfile.mkdtemp(prefix="ks-track-eval-")


def evaluate(est, truth, name):
    a, b = os.path.join(tmp, name + "_est.json"), os.path.join(tmp, name + "_truth.json")
    json.dump(est, open(a, "w"))
    json.dump(truth, open(b, "w"))
    out = subprocess.run([kinesplat, "evaluate-fit", a, b], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


rows = []
for f in track["frames"]:
    fr = ds["frames"][f["index"]]
    truth = {"body_model": "default", "betas": ds["betas"], "params": fr["pose"], "camera": fr["camera"]}
    p2 = {"body_model": "default", "betas": track["betas"], "params": f["params"], "camera": f["camera"]}
    ind = f["independent"]
    p1 = {"body_model": "default", "betas": ind["betas"], "params": ind["params"], "camera": ind["camera"]}
    m2 = evaluate(p2, truth, "p2_%d" % f["index"])
    m1 = evaluate(p1, truth, "p1_%d" % f["index"])
    rows.append({"index": f["index"], "mpjpe": m2["mpjpe_mm"], "pa": m2["pa_mpjpe_mm"],
                 "iou": m2["silhouette_iou"], "mpjpe_pass1": m1["mpjpe_mm"],
                 "pa_pass1": m1["pa_mpjpe_mm"], "iou_pass1": m1["silhouette_iou"]})


def med(k):
    return round(statistics.median(r[k] for r in rows), 1)


def dist(a, b):
    return sum((x - y) ** 2 for x, y in zip(a, b)) ** 0.5


true_b = ds["betas"]
pass1_b = [f["independent"]["betas"] for f in track["frames"]]
fx = ds["frames"][0]["camera"]["fx"]
summary = {
    "frames": len(rows),
    "median": {k: med(k) for k in ["mpjpe", "pa", "mpjpe_pass1", "pa_pass1"]},
    "median_iou": round(statistics.median(r["iou"] for r in rows), 3),
    "median_iou_pass1": round(statistics.median(r["iou_pass1"] for r in rows), 3),
    "max": {k: round(max(r[k] for r in rows), 1) for k in ["mpjpe", "pa", "mpjpe_pass1", "pa_pass1"]},
    "betas_error_shared": round(dist(track["betas"], true_b), 3),
    "betas_error_pass1_median_over_frames": round(statistics.median(dist(b, true_b) for b in pass1_b), 3),
    "betas_spread_pass1": round(statistics.median(dist(b, track["betas"]) for b in pass1_b), 3),
    "focal": track["focal"], "true_focal": fx,
    "perceive_fps": round(len(rows) / track["perceive_seconds"], 2) if track["perceive_seconds"] else None,
    "fit_fps": round(len(rows) / track["fit_seconds"], 3),
    "per_frame": [{k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()} for r in rows],
}
print(json.dumps(summary, indent=1))
