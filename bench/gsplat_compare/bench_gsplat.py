#!/usr/bin/env python3
"""Benchmark gsplat.rasterization on a 3DGS .ply scene and one camera.

usage: python3 bench_gsplat.py SCENE.ply CAMERA.json [frames=50]

Env:
  OUT           if set, write gsplat_render.npy (H,W,3 float32), gsplat_alpha.npy
                (H,W float32) and gsplat_bench.json there.
  SAVE_GRADS=1  also save gradients of the fwd+bwd loss (gsplat_grads.npz).
  LOSS_WEIGHTS  optional .npy (H,W,3) used as loss weights instead of the
                built-in numpy default_rng(0).random(...)*1e-3.

The gsplat package is expected on PYTHONPATH (see bench/gsplat_compare.sh); importing it
triggers the JIT build of its CUDA extension (torch.utils.cpp_extension.load).
"""
import json
import math
import os
import statistics
import sys
import time
import types

try:
    import numpy as np
except ImportError:  # only the pure-python header/self-check helpers work without it
    np = None


# ----------------------------------------------------------------------------
# PLY reader (pure numpy; also used by the local self-test)
# ----------------------------------------------------------------------------
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def read_ply_header(path):
    """Pure-python header parse -> (elements [(name, count, [(prop, dtype|None)])], data_start)."""
    with open(path, "rb") as f:
        first = f.readline()
        if first.strip() != b"ply":
            raise ValueError(f"{path}: not a PLY file")
        elements = []
        fmt = None
        while True:
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: header has no end_header")
            tok = line.decode("ascii", "replace").split()
            if not tok or tok[0] in ("comment", "obj_info"):
                continue
            if tok[0] == "format":
                fmt = tok[1]
            elif tok[0] == "element":
                elements.append((tok[1], int(tok[2]), []))
            elif tok[0] == "property":
                if not elements:
                    raise ValueError("property before element")
                if tok[1] == "list":
                    elements[-1][2].append((tok[4], None))
                else:
                    elements[-1][2].append((tok[2], _PLY_TYPES[tok[1]]))
            elif tok[0] == "end_header":
                break
        if fmt != "binary_little_endian":
            raise ValueError(f"{path}: only binary_little_endian supported, got {fmt}")
        return elements, f.tell()


def _vertex_layout(path):
    """-> (count, [(prop, dtype)], byte offset of the vertex block)."""
    elements, offset = read_ply_header(path)
    for name, count, props in elements:
        if any(dt is None for _, dt in props):
            raise ValueError(f"list properties in element '{name}' (before/at vertex) unsupported")
        if name == "vertex":
            return count, props, offset
        offset += count * sum(int(dt[1]) for _, dt in props)
    raise ValueError(f"{path}: no vertex element")


def read_ply_vertices(path):
    """Return (dict name -> float32 array [N], property name list)."""
    count, props, offset = _vertex_layout(path)
    dtype = np.dtype([(p, "<" + dt) for p, dt in props])
    arr = np.fromfile(path, dtype=dtype, count=count, offset=offset)
    if arr.shape[0] != count:
        raise ValueError(f"{path}: truncated ({arr.shape[0]} of {count} vertices)")
    cols = {p: np.ascontiguousarray(arr[p], dtype=np.float32) for p, _ in props}
    return cols, [p for p, _ in props]


def raw_vertex(path, i):
    """Pure-python (struct) read of vertex i -> dict prop -> float (for cross-checks)."""
    import struct
    count, props, offset = _vertex_layout(path)
    code = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I", "f4": "f", "f8": "d"}
    fmt = "<" + "".join(code[dt] for _, dt in props)
    size = struct.calcsize(fmt)
    with open(path, "rb") as f:
        f.seek(offset + i * size)
        vals = struct.unpack(fmt, f.read(size))
    return dict(zip((p for p, _ in props), vals))


def sh_coeff_from_raw(v, k, c, K):
    """SH coefficient k (0..K-1), colour channel c, from a raw vertex dict (3DGS layout)."""
    if k == 0:
        return v["f_dc_%d" % c]
    return v["f_rest_%d" % (c * (K - 1) + (k - 1))]


def check_against_raw(path, scene, idx=(0,)):
    """Compare numpy-loaded arrays with a struct read of some vertices; raises on mismatch."""
    K = scene["sh"].shape[1]
    for i in idx:
        v = raw_vertex(path, i)
        exp = {
            "means": [v["x"], v["y"], v["z"]],
            "quats": [v["rot_%d" % j] for j in range(4)],
            "log_scales": [v["scale_%d" % j] for j in range(3)],
            "opacity_logits": [v["opacity"]],
            "sh": [sh_coeff_from_raw(v, k, c, K) for k in range(K) for c in range(3)],
        }
        for key, vals in exp.items():
            got = np.asarray(scene[key][i], dtype=np.float64).reshape(-1)
            if not np.array_equal(got, np.asarray(vals, dtype=np.float32).astype(np.float64)):
                raise AssertionError(f"PLY self-check failed: vertex {i} field {key}")


def load_3dgs_ply(path):
    """Return dict of numpy float32 arrays: means [N,3], quats [N,4] (wxyz, raw),
    log_scales [N,3], opacity_logits [N], sh [N,K,3]; and sh_degree."""
    c, names = read_ply_vertices(path)
    n = c["x"].shape[0]
    means = np.stack([c["x"], c["y"], c["z"]], 1)
    f_dc = np.stack([c["f_dc_%d" % i] for i in range(3)], 1)  # [N,3]
    rest_names = sorted((p for p in names if p.startswith("f_rest_")),
                        key=lambda s: int(s[len("f_rest_"):]))
    nrest = len(rest_names)
    if nrest % 3:
        raise ValueError(f"f_rest count {nrest} not divisible by 3")
    K = nrest // 3 + 1
    deg = int(round(math.sqrt(K))) - 1
    if (deg + 1) ** 2 != K:
        raise ValueError(f"K={K} SH coefficients is not a square")
    if nrest:
        f_rest = np.stack([c[p] for p in rest_names], 1)  # [N, 3*(K-1)] channel-major
        f_rest = f_rest.reshape(n, 3, K - 1).transpose(0, 2, 1)  # [N, K-1, 3]
        sh = np.concatenate([f_dc[:, None, :], f_rest], 1)
    else:
        sh = f_dc[:, None, :]
    quats = np.stack([c["rot_%d" % i] for i in range(4)], 1)
    log_scales = np.stack([c["scale_%d" % i] for i in range(3)], 1)
    return dict(means=np.ascontiguousarray(means),
                quats=np.ascontiguousarray(quats),
                log_scales=np.ascontiguousarray(log_scales),
                opacity_logits=np.ascontiguousarray(c["opacity"]),
                sh=np.ascontiguousarray(sh, dtype=np.float32)), deg


def load_camera(path):
    with open(path) as f:
        cam = json.load(f)
    W, H = int(cam["width"]), int(cam["height"])
    R = np.asarray(cam["R"], dtype=np.float32).reshape(3, 3)
    t = np.asarray(cam["t"], dtype=np.float32).reshape(3)
    viewmat = np.eye(4, dtype=np.float32)
    viewmat[:3, :3] = R
    viewmat[:3, 3] = t
    K = np.array([[cam["fx"], 0.0, cam["cx"]],
                  [0.0, cam["fy"], cam["cy"]],
                  [0.0, 0.0, 1.0]], dtype=np.float32)
    return W, H, viewmat, K


def _stats(ms):
    return dict(median_ms=statistics.median(ms), min_ms=min(ms),
                mean_ms=statistics.fmean(ms), max_ms=max(ms), n=len(ms))


def _fmt(tag, s):
    fps = 1000.0 / s["median_ms"] if s["median_ms"] > 0 else float("inf")
    return (f"{tag:<34s} median {s['median_ms']:8.3f} ms  min {s['min_ms']:8.3f} ms  "
            f"mean {s['mean_ms']:8.3f} ms  ({fps:8.1f} FPS @median, n={s['n']})")


def timed(fn, frames):
    """Runs fn() frames times; per run the host wall time and the CUDA events' time (ms), and
    the last run's result."""
    import torch
    wall, ev = [], []
    out = None
    for _ in range(frames):
        ev0 = torch.cuda.Event(enable_timing=True)
        ev1 = torch.cuda.Event(enable_timing=True)
        torch.cuda.synchronize()
        t = time.perf_counter()
        ev0.record()
        out = fn()
        ev1.record()
        torch.cuda.synchronize()
        wall.append((time.perf_counter() - t) * 1e3)
        ev.append(ev0.elapsed_time(ev1))
    return wall, ev, out


def main():
    if len(sys.argv) < 3:
        print(__doc__)
        sys.exit(2)
    ply_path, cam_path = sys.argv[1], sys.argv[2]
    frames = int(sys.argv[3]) if len(sys.argv) > 3 else 50
    warmup = 5
    out_dir = os.environ.get("OUT")

    # ---- load inputs on CPU first (cheap, catches format errors early) ----
    t0 = time.perf_counter()
    scene, sh_deg = load_3dgs_ply(ply_path)
    check_against_raw(ply_path, scene, idx=sorted({0, scene["means"].shape[0] // 2,
                                                    scene["means"].shape[0] - 1}))
    W, H, viewmat_np, K_np = load_camera(cam_path)
    n = scene["means"].shape[0]
    print(f"[bench] loaded {ply_path}: N={n} gaussians, SH degree {sh_deg} "
          f"(K={scene['sh'].shape[1]}), {time.perf_counter() - t0:.2f}s", flush=True)
    print(f"[bench] camera {cam_path}: {W}x{H}, fx={K_np[0,0]:.3f} fy={K_np[1,1]:.3f} "
          f"cx={K_np[0,2]:.3f} cy={K_np[1,2]:.3f}", flush=True)

    import torch
    print(f"[bench] torch {torch.__version__} (CUDA {torch.version.cuda}), "
          f"TORCH_CUDA_ARCH_LIST={os.environ.get('TORCH_CUDA_ARCH_LIST')}, "
          f"MAX_JOBS={os.environ.get('MAX_JOBS')}, "
          f"TORCH_EXTENSIONS_DIR={os.environ.get('TORCH_EXTENSIONS_DIR')}", flush=True)
    if not torch.cuda.is_available():
        print("[bench] ERROR: torch.cuda.is_available() is False")
        sys.exit(4)
    gpu = torch.cuda.get_device_name(0)
    print(f"[bench] GPU: {gpu} (cc {torch.cuda.get_device_capability(0)})", flush=True)

    # gsplat/cuda/_backend.py does an unconditional `from rich.console import Console`;
    # provide a tiny stand-in if rich is not installed (it is only used for messages).
    try:
        import rich.console  # noqa: F401
    except ImportError:
        class _Console:
            def print(self, *a, **k):
                print(*a)

            def status(self, *a, **k):
                import contextlib
                print(*a)
                return contextlib.nullcontext()
        rich_mod = types.ModuleType("rich")
        cons_mod = types.ModuleType("rich.console")
        cons_mod.Console = _Console
        rich_mod.console = cons_mod
        sys.modules["rich"] = rich_mod
        sys.modules["rich.console"] = cons_mod
        print("[bench] note: 'rich' not installed, using a stub", flush=True)

    # ---- JIT build: `import gsplat` triggers gsplat.cuda._backend -> build_and_load_gsplat ----
    ext_dir = os.environ.get("TORCH_EXTENSIONS_DIR", "")
    so_path = os.path.join(ext_dir, "gsplat_cuda", "gsplat_cuda.so") if ext_dir else ""
    prebuilt = bool(so_path) and os.path.exists(so_path)
    print(f"[bench] building/loading gsplat CUDA extension (cached .so present: {prebuilt}) ...",
          flush=True)
    tb = time.perf_counter()
    try:
        import gsplat
        from gsplat.cuda._backend import _C
    except Exception as e:  # build failure
        import traceback
        traceback.print_exc()
        print(f"[bench] GSPLAT_BUILD_FAILED after {time.perf_counter() - tb:.1f}s: "
              f"{type(e).__name__}", flush=True)
        sys.exit(3)
    build_s = time.perf_counter() - tb
    if _C is None:
        print("[bench] GSPLAT_BUILD_FAILED: gsplat reports no CUDA toolkit (_C is None)")
        sys.exit(3)
    commit = os.environ.get("GSPLAT_COMMIT", "?")
    print(f"[bench] JIT build+load (import gsplat) took {build_s:.1f} s "
          f"({'cached' if prebuilt else 'fresh build'})", flush=True)
    print(f"[bench] gsplat {gsplat.__version__} commit {commit} from {os.path.dirname(gsplat.__file__)}",
          flush=True)
    try:
        print(f"[bench] gsplat build_config: {dict(_C.build_config())}", flush=True)
    except Exception:
        pass

    dev = torch.device("cuda")
    means = torch.from_numpy(scene["means"]).to(dev)
    quats = torch.from_numpy(scene["quats"]).to(dev)
    scales = torch.exp(torch.from_numpy(scene["log_scales"]).to(dev))
    opacities = torch.sigmoid(torch.from_numpy(scene["opacity_logits"]).to(dev))
    sh = torch.from_numpy(scene["sh"]).to(dev)  # [N,K,3]
    viewmats = torch.from_numpy(viewmat_np).to(dev)[None]  # [1,4,4]
    Ks = torch.from_numpy(K_np).to(dev)[None]  # [1,3,3]

    def render(m, q, s, o, c):
        img, alpha, meta = gsplat.rasterization(
            m, q, s, o, c, viewmats, Ks, W, H,
            near_plane=0.01, eps2d=0.3, sh_degree=sh_deg,
            packed=False, backgrounds=None, render_mode="RGB",
            rasterize_mode="classic",  # tile_size left at its default (16)
        )
        return img, alpha, meta

    # ---------------- forward only ----------------
    with torch.no_grad():
        for _ in range(warmup):
            img, alpha, meta = render(means, quats, scales, opacities, sh)
        torch.cuda.synchronize()
        n_vis = int((meta["radii"] > 0).any(-1).sum().item()) if meta.get("radii") is not None else -1
        n_isect = int(meta["isect_ids"].numel()) if meta.get("isect_ids") is not None else -1
        print(f"[bench] image {img.shape[-2]}x{img.shape[-3]} (W x H), tile_size={meta.get('tile_size')}, "
              f"visible gaussians {n_vis}, tile intersections {n_isect}", flush=True)

        fwd_wall, fwd_ev, (img, alpha, meta) = timed(
            lambda: render(means, quats, scales, opacities, sh), frames)
        fwd_img = img[0].float().cpu().numpy()  # [H,W,3]
        fwd_alpha = alpha[0, ..., 0].float().cpu().numpy()

    # ---------------- forward + backward ----------------
    params = [t.detach().clone().requires_grad_(True) for t in (means, quats, scales, opacities, sh)]
    lw_path = os.environ.get("LOSS_WEIGHTS")
    if lw_path:
        lw_np = np.load(lw_path).astype(np.float32).reshape(H, W, 3)
    else:
        lw_np = (np.random.default_rng(0).random((H, W, 3), dtype=np.float32) * 1e-3)
    loss_w = torch.from_numpy(lw_np).to(dev)[None]

    def step():
        for p in params:
            p.grad = None
        img, _, _ = render(*params)
        loss = (img * loss_w).sum()
        loss.backward()
        return loss

    for _ in range(warmup):
        loss = step()
    torch.cuda.synchronize()
    bwd_wall, bwd_ev, loss = timed(step, frames)

    res = dict(
        gsplat_version=gsplat.__version__, gsplat_commit=commit, gpu=gpu,
        torch=torch.__version__, n_gaussians=n, sh_degree=sh_deg, width=W, height=H,
        visible_gaussians=n_vis, tile_intersections=n_isect, frames=frames, warmup=warmup,
        jit_build_s=build_s, jit_cached=prebuilt, loss=float(loss.item()),
        fwd_wall=_stats(fwd_wall), fwd_event=_stats(fwd_ev),
        fwdbwd_wall=_stats(bwd_wall), fwdbwd_event=_stats(bwd_ev),
        image_mean_rgb=[float(x) for x in fwd_img.reshape(-1, 3).mean(0)],
        alpha_mean=float(fwd_alpha.mean()),
    )
    print("")
    print(f"== gsplat {gsplat.__version__} ({commit[:12]}) on {gpu}: N={n}, SH deg {sh_deg}, "
          f"{W}x{H}, frames={frames} (+{warmup} warm-up) ==")
    print(_fmt("forward (wall, sync+perf_counter)", res["fwd_wall"]))
    print(_fmt("forward (cuda events)", res["fwd_event"]))
    print(_fmt("fwd+bwd (wall, sync+perf_counter)", res["fwdbwd_wall"]))
    print(_fmt("fwd+bwd (cuda events)", res["fwdbwd_event"]))
    print(f"image mean RGB {res['image_mean_rgb']}, alpha mean {res['alpha_mean']:.6f}, "
          f"loss {res['loss']:.6e}")
    print("BENCH_JSON " + json.dumps(res))

    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        np.save(os.path.join(out_dir, "gsplat_render.npy"), fwd_img.astype(np.float32))
        np.save(os.path.join(out_dir, "gsplat_alpha.npy"), fwd_alpha.astype(np.float32))
        with open(os.path.join(out_dir, "gsplat_bench.json"), "w") as f:
            json.dump(res, f, indent=1)
        if os.environ.get("SAVE_GRADS") == "1":
            names = ("means", "quats", "scales", "opacities", "sh")
            np.savez(os.path.join(out_dir, "gsplat_grads.npz"),
                     **{k: p.grad.float().cpu().numpy() for k, p in zip(names, params)})
        print(f"[bench] wrote results to {out_dir}")


if __name__ == "__main__":
    main()
