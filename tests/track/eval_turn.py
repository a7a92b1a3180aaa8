#!/usr/bin/python3
"""The body's turn in every frame of a `kinesplat track` output of a turntable with known cameras.

usage: eval_turn.py TRACK CAMERAS.json
CAMERAS.json: `views`, each with `matrix_4x4` (world-to-camera, OpenCV axes) and `fx`, for frame k
= view k (../shared/samples/idol_turn/cameras.json). The person stands still while the camera
orbits, so frame k's body seen from its camera is R_k W for one unknown world orientation W. The
track's body in its camera is C G_k (C the fit's fixed camera rotation, G_k the frame's
global_orient). W is fitted to all frames at once (the rotation nearest the mean of R_k^T C G_k);
per frame the angle between C G_k and R_k W (degrees), and its yaw part (about the body's up
axis). Prints a JSON summary for `params` (pass 3 where it ran; with `--avatar` the registered
pose, and the keypoint track's as `keypoint`), `shared` (pass 2) and
`independent` (pass 1), and the focal found beside the true one."""
import json, os, sys
import numpy as np

track_dir, cameras = sys.argv[1:3]
track = json.load(open(os.path.join(track_dir, "track.json")))
cams = json.load(open(cameras))["views"]
C = np.diag([1.0, -1.0, -1.0])


def rodrigues(v):
    v = np.asarray(v, float)
    a = np.linalg.norm(v)
    if a < 1e-12:
        return np.eye(3)
    k = v / a
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


def angle(R):
    return np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


def evaluate(key):
    E, T = [], []
    for f in track["frames"]:
        p = f["params"] if key == "params" else f["registration"]["keypoint_params"] \
            if key == "registration" else f[key]["params"]
        E.append(C @ rodrigues(p["global_orient"]))
        T.append(np.array(cams[f["index"]]["matrix_4x4"])[:3, :3])
    M = sum(t.T @ e for t, e in zip(T, E))
    U, _, Vt = np.linalg.svd(M)
    W = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    err, yaw = [], []
    for t, e in zip(T, E):
        D = (t @ W).T @ e  # the error in the body's frame
        err.append(angle(D))
        yaw.append(abs(np.degrees(np.arctan2(D[0, 2] - D[2, 0], D[0, 0] + D[2, 2]))))
    return {"median_deg": round(float(np.median(err)), 1), "max_deg": round(float(np.max(err)), 1),
            "median_yaw_deg": round(float(np.median(yaw)), 1), "max_yaw_deg": round(float(np.max(yaw)), 1),
            "per_frame_deg": [round(float(x), 1) for x in err]}


out = {"frames": len(track["frames"]), "focal": track["focal"], "focal_from": track.get("focal_from"),
       "true_focal_scaled": cams[0]["fx"] * track["width"] / json.load(open(cameras))["image_size"][0]}
for key, name in [("params", "result"), ("registration", "keypoint"), ("shared", "pass2"),
                  ("independent", "pass1")]:
    if key == "params" or key in track["frames"][0]:
        out[name] = evaluate(key)
print(json.dumps(out, indent=1))
