#!/usr/bin/env python3
"""Per-frame MPJPE / PA-MPJPE and the acceleration error of a `kinesplat track` output against a
synth's truth.

usage: eval_track.py KINESPLAT TRACK SYNTH_TRAIN_DIR
Each frame's result (`params`: pass 3 on a sequence, else pass 2; with `--avatar` the registered
pose, and the keypoint track's as `keypoint`), its pass-2 fit with the shared
shape (`shared`) and its independent fit (pass 1) are written as fit.json files and compared with
the synth frame's true pose and camera by `kinesplat evaluate-fit`; the kept frames' indices select
the dataset frames. The acceleration error (mm / frame^2, over the kept frames' steps): per joint
the second difference of the pelvis-relative camera-frame joints, estimate against truth, mean
over joints and frames (as VIBE and TCMR report it). Prints a JSON summary (medians, per frame)."""
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


def variants(f):
    out = {"result": (track["betas"], f["params"], f["camera"])}
    if "shared" in f:
        out["pass2"] = (track["betas"], f["shared"]["params"], f["shared"]["camera"])
    if "registration" in f:  # pass 4: `params` is the registered pose, this the keypoint track's
        out["keypoint"] = (track["betas"], f["registration"]["keypoint_params"], f["camera"])
    ind = f["independent"]
    out["pass1"] = (ind["betas"], ind["params"], ind["camera"])
    return out


rows, joints, per_joint = [], {}, {}
JOINTS = ["pelvis", "l_hip", "r_hip", "spine1", "l_knee", "r_knee", "spine2", "l_ankle", "r_ankle",
          "spine3", "l_foot", "r_foot", "neck", "l_collar", "r_collar", "head", "l_shoulder",
          "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_hand", "r_hand"]
for f in track["frames"]:
    fr = ds["frames"][f["index"]]
    truth = {"body_model": "default", "betas": ds["betas"], "params": fr["pose"], "camera": fr["camera"]}
    row = {"index": f["index"], "swapped": f.get("swapped", False), "restarted": f.get("restarted", False)}
    for name, (betas, params, camera) in variants(f).items():
        m = evaluate({"body_model": "default", "betas": betas, "params": params, "camera": camera},
                     truth, "%s_%d" % (name, f["index"]))
        row["mpjpe_" + name] = m["mpjpe_mm"]
        row["pa_" + name] = m["pa_mpjpe_mm"]
        row["iou_" + name] = m["silhouette_iou"]
        row["shape_" + name] = m["rest_vertex_error_mm"]
        joints.setdefault(name, []).append(m["estimate_joints_mm"])
        per_joint.setdefault(name, []).append(m["pa_per_joint_mm"])
        row.setdefault("_truth", m["truth_joints_mm"])
    rows.append(row)


def accel_error(est, tru):
    errs = []
    for i in range(1, len(est) - 1):
        e = 0.0
        for j in range(len(est[i])):
            ae = [est[i - 1][j][k] - 2 * est[i][j][k] + est[i + 1][j][k] for k in range(3)]
            at = [tru[i - 1][j][k] - 2 * tru[i][j][k] + tru[i + 1][j][k] for k in range(3)]
            e += sum((a - b) ** 2 for a, b in zip(ae, at)) ** 0.5
        errs.append(e / len(est[i]))
    return round(statistics.mean(errs), 2) if errs else None


def dist(a, b):
    return sum((x - y) ** 2 for x, y in zip(a, b)) ** 0.5


names = [n for n in ["result", "keypoint", "pass2", "pass1"] if "mpjpe_" + n in rows[0]]
truth_joints = [r.pop("_truth") for r in rows]
true_b = ds["betas"]
pass1_b = [f["independent"]["betas"] for f in track["frames"]]
fx = ds["frames"][0]["camera"]["fx"]
summary = {
    "frames": len(rows),
    "median": {k + "_" + n: round(statistics.median(r[k + "_" + n] for r in rows), 1)
               for n in names for k in ["mpjpe", "pa"]},
    "median_iou": {n: round(statistics.median(r["iou_" + n] for r in rows), 3) for n in names},
    # the shape's error: rest-pose bodies, pelvis on pelvis, mean vertex distance (mm)
    "median_rest_vertex_error_mm": {n: round(statistics.median(r["shape_" + n] for r in rows), 1)
                                    for n in names},
    "max": {k + "_" + n: round(max(r[k + "_" + n] for r in rows), 1) for n in names for k in ["mpjpe", "pa"]},
    "pa_per_joint_median_mm": {n: {JOINTS[j] if j < len(JOINTS) else str(j):
                                   round(statistics.median(f[j] for f in per_joint[n]), 1)
                                   for j in range(len(per_joint[n][0]))} for n in names},
    "accel_error_mm_per_frame2": {n: accel_error(joints[n], truth_joints) for n in names},
    "accel_truth_mm_per_frame2": accel_error([[[0, 0, 0]] * len(t) for t in truth_joints], truth_joints),
    "swapped": sum(r["swapped"] for r in rows), "restarted": sum(r["restarted"] for r in rows),
    "betas_error_shared": round(dist(track["betas"], true_b), 3),
    "betas_error_pass1_median_over_frames": round(statistics.median(dist(b, true_b) for b in pass1_b), 3),
    "focal": track["focal"], "true_focal": fx,
    "perceive_fps": round(len(rows) / track["perceive_seconds"], 2) if track["perceive_seconds"] else None,
    "fit_fps": round(len(rows) / track["fit_seconds"], 3),
    "temporal": track.get("temporal"),
    "per_frame": [{k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()} for r in rows],
}
print(json.dumps(summary, indent=1))
