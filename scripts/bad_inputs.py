"""Malformed inputs against every command (issue 16): each must exit with code 2 and one
stderr line starting "error:", with no traceback and no output file left behind.

    python scripts/bad_inputs.py

Builds its own fixtures in a temporary folder (a small sweep file and synthetic drops),
runs about 240 malformed invocations of the installed `dice-sweep` (two at a time) and
prints each one that breaks the rule, then the count that keep it. Exit code 1 if any breaks it.
"""
import gzip
import os
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
C = str(Path(__file__).resolve().parent.parent / "configs")
T = Path(tempfile.mkdtemp(prefix="bad_inputs_"))
W = T / "work"
W.mkdir()
env0 = dict(os.environ, DICE_SWEEP_COMPILE_NOTE="0")
subprocess.run(["dice-sweep", "sweep", f"{C}/demo.toml", "-o", str(T / "good.h5"), "--set", "grid.x.num=16", "--set", "grid.y.num=16", "--quiet"], check=True, env=env0)
subprocess.run(["dice-sweep", "simulate-drops", f"{C}/square_drops.toml", "-o", str(T / "drops.csv"), "--tracks", "6", "--seed", "1"], check=True, env=env0, capture_output=True)
def w(name, data, mode="w"):
    p = W / name
    if isinstance(data, bytes): p.write_bytes(data)
    else: p.write_text(data)
    return str(p)
demo = open(f"{C}/demo.toml").read()
table1 = open(f"{C}/table1.toml").read()
sq = open(f"{C}/square_drops.toml").read()
good_csv = (T/"drops.csv").read_text()
F = {
 "missing": str(W/"nope.toml"), "dir": str(W), "empty": w("empty.h5", ""), "binary": w("bin.toml", b"\x00\xff\xfe\x89PNG"),
 "badtoml": w("bad.toml", "[die\nsides = 4"), "unknown_sec": w("us.toml", table1 + "\n[foo]\nx = 1\n"),
 "nan": w("nan.toml", table1.replace("y0 = 0.15", "y0 = nan")), "inf": w("inf.toml", table1.replace("y0 = 0.15", "y0 = inf")),
 "str_num": w("sn.toml", table1.replace("y0 = 0.15", 'y0 = "high"')), "bool": w("bool.toml", table1.replace("sides = 4", "sides = true")),
 "float_sides": w("fs.toml", table1.replace("sides = 4", "sides = 4.5")), "list": w("list.toml", table1.replace("y0 = 0.15", "y0 = [0.1]")),
 "neg_r": w("negr.toml", table1.replace("circumradius = 0.013435028842544402", "circumradius = -0.01")),
 "below": w("below.toml", table1.replace("y0 = 0.15", "y0 = 0.001")), "tmax0": w("tm.toml", table1.replace("t_max = 30.0", "t_max = 0")),
 "bom": w("bom.toml", "\ufeff" + table1), "latin1": w("l1.toml", (table1 + "# caf\xe9\n").encode("latin-1")),
 "dup": w("dup.toml", table1.replace("y0 = 0.15", "y0 = 0.15\ny0 = 0.2")),
 "grid_minmax": w("gmm.toml", demo.replace("min = 0.0, max = 60.0", "min = 60.0, max = 0.0")),
 "grid_param": w("gp.toml", demo.replace('param = "omega0"', 'param = "omega"')),
 "grid_same": w("gs.toml", demo.replace('param = "omega0"', 'param = "y0"')),
 "grid_num": w("gn.toml", demo.replace("num = 128 }  # rad/s", "num = 1000000000 }")),
 "grid_below": w("gb.toml", demo.replace("min = 0.02", "min = -0.5")),
 "csv_empty": w("e.csv", ""), "csv_header": w("h.csv", "traj,t,x,y,phi\n"), "csv_badhead": w("bh.csv", "a,b,c\n1,2,3\n"),
 "csv_text": w("tx.csv", good_csv.replace("0.1350882931", "abc", 1)), "csv_nan": w("nan.csv", "traj,t,x,y,phi\n" + "".join(f"1,{i*0.004},nan,nan,nan\n" for i in range(50))),
 "csv_short": w("sh.csv", "traj,t,x,y,phi\n1,0,0,0.1,0\n"), "gz_bad": w("bad.csv.gz", b"not gzip at all"),
 "gz_trunc": w("tr.csv.gz", gzip.compress(good_csv.encode())[:200]), "csv_bin": w("b.csv", b"\x00\x01\x02\xff"*100),
 "csv_dupt": w("dt.csv", "traj,t,x,y,phi\n" + "1,0,0,0.1,0\n"*40),
 "csv_backt": w("bt.csv", "traj,t,x,y,phi\n" + "".join(f"1,{-i*0.004},0,{0.1+i*1e-4},0\n" for i in range(40))),
 "h5_not": w("not.h5", b"hello"), "h5_other": None, "h5_trunc": None,

}
import h5py, numpy as np
with h5py.File(W/"other.h5", "w") as f: f["x"] = np.arange(3)
F["h5_other"] = str(W/"other.h5")
good = (T/"good.h5").read_bytes(); F["h5_trunc"] = w("trunc.h5", good[: len(good)//2])
G = str(T/"good.h5"); D = str(T/"drops.csv")
cases = []
def add(*args, out=None):
    cases.append((list(args), out))


def issue32_io_cases():
    """Issue 32, items 1-3 (branch io32): a full disk, forged files, values that cannot be computed,
    FIFOs and devices as inputs. Kept in one block, apart from the cases of items 4-6."""
    import atexit
    import json
    sys.path.insert(0, str(Path(C).parent))
    from tests.helpers import replace_dataset as replace, set_first
    X = T / "io32"
    X.mkdir()
    # -- item 2: sweep files that do not fit docs/hdf5.md, drawn, merged, measured, controlled, served
    def forge(name, change):
        path = X / f"{name}.h5"
        path.write_bytes(good)
        with h5py.File(path, "r+") as h5:
            change(h5)
        return str(path)
    forged = {
        "shape": lambda h5: replace(h5, "outcome", np.zeros((3, 5), np.int8)),
        "float": lambda h5: replace(h5, "outcome", h5["outcome"][...].astype(np.float32)),
        "fifty": set_first("outcome", 50), "minus128": lambda h5: (set_first("outcome", -128)(h5), set_first("status", 0)(h5)),
        "sides0": lambda h5: h5.attrs.__setitem__("sides", 0), "sides500": lambda h5: h5.attrs.__setitem__("sides", 500),
        "same_axes": lambda h5: h5.attrs.__setitem__("x_param", h5.attrs["y_param"]),
        "axis_inf": lambda h5: h5["omega0"].__setitem__(3, np.inf),
        "axis_down": lambda h5: h5["omega0"].__setitem__(3, -1.0),
        "status_shape": lambda h5: replace(h5, "status", np.zeros((4, 4), np.uint8)),
        "shard": lambda h5: h5.attrs.__setitem__("shard", "5/2"),
    }
    for key, change in forged.items():
        path = forge(key, change)
        add("plot", path, "-o", str(X / f"p_{key}.png"), out=X / f"p_{key}.png")
        add("merge", path, "-o", str(X / f"m_{key}.h5"), out=X / f"m_{key}.h5")
        add("measure", path, "--json", str(X / f"j_{key}.json"), out=X / f"j_{key}.json")
        add("control", path, "--sigma", "y0=0.01", "-o", str(X / f"c_{key}.npz"), out=X / f"c_{key}.npz")
        add("view", path, "--no-open", "--port", "0")
        add("sweep", f"{C}/demo.toml", "-o", path, "--resume", "--set", "grid.x.num=16", "--set", "grid.y.num=16")
    # -- item 2: fit JSONs edited by hand, refused by forecast before the work
    rng = np.random.default_rng(0)
    paper = {"beta_normal": 0.2, "beta_tangential": -0.35}
    def fit(name, **changes):
        data = {"model": "paper", "effects": [], "params": {k: {"value": v, "ci95": [v - 0.01, v + 0.01]} for k, v in paper.items()},
                "angle_reading": "as-is: unchanged", "die": {"sides": 4, "circumradius": 0.042426406871192854},
                "split": {"confirm_fraction": 0.3, "seed": 0},
                "bootstrap_draws": {"names": list(paper), "values": (np.array(list(paper.values())) + 0.005 * rng.normal(size=(50, 2))).tolist()}}
        data.update(changes)
        path = X / f"fit_{name}.json"
        path.write_text(json.dumps(data))
        return str(path)
    fits = [fit("beta5", params={"beta_normal": {"value": 5.0}, "beta_tangential": {"value": -0.35}}),
            fit("draws", bootstrap_draws={"names": list(paper), "values": [[0.2, -0.35], [1.7, -0.35]]}),
            fit("model", model="no_such_model"),
            fit("fraction1", split={"confirm_fraction": 1.0, "seed": 0}, train_tracks=28, test_tracks=39),
            fit("fraction0", split={"confirm_fraction": 0.0, "seed": 0}),
            fit("counts", train_tracks=28, test_tracks=39)]
    for path in fits:
        out = X / (Path(path).stem + "_f.json")
        add("forecast", D, "--config", f"{C}/square_drops.toml", "--fit", path, "--json", str(out), out=out)
    # -- item 3: values that cannot be computed, refused up front
    huge = ["--set", "grid.x.min=-1e308", "--set", "grid.x.max=1e308"]
    add("sweep", f"{C}/demo.toml", "-o", str(X / "huge.h5"), *huge, out=X / "huge.h5")
    add("sweep", f"{C}/demo.toml", "-o", str(X / "tiny.h5"), "--set", "grid.x.min=1", "--set", "grid.x.max=1.0000000000000002", out=X / "tiny.h5")
    add("roll", f"{C}/table1.toml", "--set", "initial.vx0=1e200")
    add("roll", f"{C}/table1.toml", "--set", "initial.vx0=1e200", "--json")
    add("roll", f"{C}/table1.toml", "--set", "initial.omega0=1e300", "--json")
    add("roll", f"{C}/table1.toml", "--set", "initial.y0=1e308")
    add("sweep", f"{C}/demo.toml", "-o", str(X / "fast.h5"), "--set", "grid.x.max=1e9", out=X / "fast.h5")
    budget = ["--set", "integrator.dt=1e-12", "--set", f"integrator.max_events={2**62}"]
    add("roll", f"{C}/table1.toml", *budget)
    add("roll", f"{C}/table1.toml", *budget, "--set", "integrator.method=fixed_step")
    add("roll", f"{C}/table1.toml", "--set", "integrator.dt=1e-12", "--set", "integrator.method=fixed_step")
    add("sweep", f"{C}/demo.toml", "-o", str(X / "budget.h5"), *budget, out=X / "budget.h5")
    add("simulate-drops", f"{C}/square_drops.toml", "-o", str(X / "budget.csv"), "--tracks", "2", *budget, out=X / "budget.csv")
    fifo = X / "fifo"
    os.mkfifo(fifo)
    for source in (str(fifo), "/dev/zero"):
        add("roll", source)
        add("sweep", source, "-o", str(X / "f.h5"), out=X / "f.h5")
        for cmd in ("fit", "calibrate"):
            add(cmd, source, "--config", f"{C}/square_drops.toml")
            add(cmd, D, "--config", source)
        add("diagnose", source, "--config", f"{C}/square_drops.toml", "--json", str(X / "d.json"), out=X / "d.json")
        add("forecast", source, "--config", f"{C}/square_drops.toml", "--fit", fits[0], "--json", str(X / "f.json"), out=X / "f.json")
        add("forecast", D, "--config", f"{C}/square_drops.toml", "--fit", source, "--json", str(X / "f.json"), out=X / "f.json")
        add("plot", source, "-o", str(X / "f.png"), out=X / "f.png")
        add("merge", source, "-o", str(X / "f.h5"), out=X / "f.h5")
        add("measure", source)
        add("control", source, "--sigma", "y0=0.01")
    # -- item 1: a full disk (a small tmpfs; root only): one line naming the file, nothing left
    disk = X / "disk"
    disk.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], capture_output=True).returncode:
        print("issue 32 full-disk cases skipped: mounting a tmpfs needs root")
        return
    atexit.register(subprocess.run, ["umount", "-l", str(disk)], check=False)
    with open(disk / "ballast", "wb") as ballast:  # no byte left
        ballast.write(b"\0" * (os.statvfs(disk).f_bavail * os.statvfs(disk).f_frsize))
    full = lambda name: (str(disk / name), disk / name)
    for args, name in [(["sweep", f"{C}/demo.toml", "--set", "grid.x.num=16", "--set", "grid.y.num=16", "-o"], "s.h5"),
                       (["merge", G, "-o"], "m.h5"), (["plot", G, "-o"], "p.png"), (["roll", f"{C}/table1.toml", "--gif"], "r.gif"),
                       (["roll", f"{C}/table1.toml", "--png"], "r.png"), (["simulate-drops", f"{C}/square_drops.toml", "--tracks", "3", "-o"], "d.csv"),
                       (["calibrate", D, "--config", f"{C}/square_drops.toml", "--json"], "c.json"), (["measure", G, "--json"], "m.json"),
                       (["control", G, "--sigma", "y0=0.01", "-o"], "c.npz"), (["control", G, "--sigma", "y0=0.01", "--json"], "c.json"),
                       (["forecast", D, "--config", f"{C}/square_drops.toml", "--fit", fit("good"), "--members", "1000", "--map-size", "0", "--quiet", "--json"], "f.json")]:
        text, out = full(name)
        add(*args, text, out=out)


issue32_io_cases()
for key in ["missing","dir","binary","badtoml","unknown_sec","nan","inf","str_num","bool","float_sides","list","neg_r","below","tmax0","bom","latin1","dup"]:
    add("roll", F[key])
for key in ["grid_minmax","grid_param","grid_same","grid_num","grid_below","nan","missing"]:
    add("sweep", F[key], "-o", str(W/f"s_{key}.h5"), out=W/f"s_{key}.h5")
# initial.y0=-1 puts the roll's start in the table (fig08 sweeps y0, roll starts from [initial])
add("roll", f"{C}/fig08.toml", "--set", "initial.y0=-1")
for k, s in enumerate(["initial.y0=abc", "nokey", "die.sides=2", "grid.x.num=0", "die.=3", "=3", "initial.y0=", "integrator.method=rk4", "contact.model=foo", "world.g=-9.81", "world.g=0", "contact.beta_normal=1.5", "contact.friction=-1", "effects.air_drag=-1", "effects.foo=1", "contact.friction_rule=exakt", "contact.restitution=7", "effects.inertia=4", "effects.inertia=0", "effects.corner_radius=0.5", "effects.corner_radius=-1", "effects.com_offset=[0.02, 0]", "grid.x.min=nan", "grid.x.param=foo", "grid.y.min=-0.5"]):
    add("roll", f"{C}/fig08.toml", "--set", s)
    add("sweep", f"{C}/demo.toml", "-o", str(W/f"set{k}.h5"), "--set", s, out=W/f"set{k}.h5")
sw = lambda *a, out="sw.h5": add("sweep", f"{C}/demo.toml", "-o", str(W/out), *a, out=W/out)
for a in [("--workers","0"),("--workers","-1"),("--workers","99999"),("--workers","x"),("--shard","3/2"),("--shard","a/b"),("--shard","0/0"),("--shard","1"),("--shard","-1/2"),
          ("--refine","-1"),("--refine","100"),("--refine","x"),("--executor","foo"),("--scheduler","tcp://x:1"),("--png","/missing/dir/a.png"),("--png",str(W/"a.xyz")),("--png",str(W/"p.h5")),("--png",str(W))]:
    sw(*a)
add("sweep", f"{C}/table1.toml", "-o", str(W/"nogrid.h5"), out=W/"nogrid.h5")
add("sweep", f"{C}/demo.toml", "-o", str(W), out=None)
add("sweep", f"{C}/demo.toml", "-o", str(W/"x.png"), out=W/"x.png")
add("sweep", f"{C}/demo.toml", "-o", "/proc/x.h5")
add("sweep", f"{C}/demo.toml", "-o", "")
add("sweep", f"{C}/demo.toml", "-o", G)  # exists
add("sweep", f"{C}/fig08.toml", "-o", G, "--resume")  # other run
add("merge", "-o", str(W/"m.h5"), out=W/"m.h5")
add("merge", F["missing"], "-o", str(W/"m.h5"), out=W/"m.h5")
add("merge", F["h5_not"], "-o", str(W/"m.h5"), out=W/"m.h5")
add("merge", G, F["h5_other"], "-o", str(W/"m.h5"), out=W/"m.h5")
add("merge", G, "-o", G)
add("merge", G, G, "-o", str(W/"m.h5"), out=W/"m.h5")
for key in ["missing","dir","h5_not","h5_other","h5_trunc","empty"]:
    add("plot", F[key], "-o", str(W/f"p_{key}.png"), out=W/f"p_{key}.png")
for a in [("--dpi","0"),("--dpi","100000"),("--dpi","x"),("--box","1,2,3"),("--box","nan,1,2,3"),("--box","5,1,0.1,0.2"),("--box","a,b,c,d"),("-o",str(W/"b.xyz")),("-o","/missing/x.png"),("-o",str(W))]:
    add("plot", G, "-o", str(W/"pp.png"), *a, out=W/"pp.png")
for a in [("--box-size","0"),("--box-size","-3"),("--box-size","100000"),("--json",str(W)),("--json","/missing/a.json"),("--png",G),("--json",str(W/"a.txt"))]:
    add("measure", G, *a)
for key in ["missing","h5_not","h5_other","h5_trunc"]:
    add("measure", F[key])
for a in [("--sigma","omega0"),("--sigma","omega0=-1"),("--sigma","foo=1"),("--sigma","omega0=nan"),("--sigma","omega0=abc"),("--samples","0"),("--points","0"),("--seed","-1"),("--method","foo"),("-o",str(W/"c.txt")),("--workers","0"),("--png",G)]:
    add("control", G, *a)
add("control", G)  # no --sigma
for cmd in ["fit","calibrate","diagnose"]:
    for key in ["missing","dir","csv_empty","csv_header","csv_badhead","csv_text","csv_nan","csv_short","gz_bad","gz_trunc","csv_bin","csv_dupt","csv_backt"]:
        add(cmd, F[key], "--config", f"{C}/square_drops.toml")
    for a in [("--rate","0"),("--rate","-5"),("--rate","nan"),("--rate","x"),("--angle","foo"),("--config",F["missing"]),("--config",F["nan"]),("--json",str(W)),("--json","/missing/r.json"),("--png",G)]:
        add(cmd, D, "--config", f"{C}/square_drops.toml", *a)
    add(cmd, D)
add("fit", D, "--config", f"{C}/square_drops.toml", "--effects", "foo")
add("fit", D, "--config", f"{C}/square_drops.toml", "--effects", ",")
add("diagnose", D, "--config", f"{C}/square_drops.toml", "--md", str(W/"r.txt"))
add("calibrate", D, "--config", f"{C}/square_drops.toml", "--gaps", "foo")
sd = lambda *a, out="sd.csv": add("simulate-drops", f"{C}/square_drops.toml", "-o", str(W/out), *a, out=W/out)
for a in [("--tracks","0"),("--tracks","x"),("--tracks","-2"),("--tracks","1000001"),("--tracks","3","--noise","1,2"),("--tracks","3","--noise","-1,0,0"),("--tracks","3","--noise","a,b,c"),
          ("--tracks","3","--drop-prob","1.5"),("--tracks","3","--glitch-prob","-0.1"),("--tracks","3","--duration","0"),("--tracks","3","--duration","nan"),("--tracks","3","--range","foo=1:2"),
          ("--tracks","3","--range","y0=2:1"),("--tracks","3","--range","y0=-1:0"),("--tracks","3","--range","y0"),("--tracks","3","--initial","foo"),("--tracks","3","--rate","0"),("--tracks","3","--seed","-1"),("--tracks","3","--set","die.sides=2")]:
    sd(*a)
add("simulate-drops", f"{C}/square_drops.toml", "-o", str(W/"x.txt"), "--tracks", "3", out=W/"x.txt")
add("simulate-drops", f"{C}/square_drops.toml", "-o", str(W), "--tracks", "3")
add("simulate-drops", F["missing"], "-o", str(W/"y.csv"), "--tracks", "3", out=W/"y.csv")
# --- issue 32, items 4 and 5 (branch truth32): options given twice, the README's sides range ---
def issue32_repeats_and_readme_cases():
    """Every option of every command that takes one value, given twice (click kept the last,
    silently); repeatable options naming one key twice; sides beyond the README's 3 to 127."""
    from dice_sweep.cli import main
    import click
    suffix = {"--output": {"sweep": ".h5", "merge": ".h5", "plot": ".png", "control": ".npz", "simulate-drops": ".csv"},
              "--json": ".json", "--md": ".md", "--png": ".png", "--gif": ".gif"}
    for name, command in sorted(main.commands.items()):
        for param in command.params:
            if not isinstance(param, click.Option) or param.is_flag or param.multiple:
                continue
            opt = max(param.opts, key=len)
            ext = suffix.get(opt)
            ext = ext.get(name, ".out") if isinstance(ext, dict) else ext
            if ext:  # an output given twice: neither file may appear
                first, second = (W / f"twice_{name}_{opt[2:]}_{k}{ext}" for k in (1, 2))
                add(name, G if name in ("plot", "measure", "control", "view") else D, opt, str(first), opt, str(second), out=second)
            else:
                add(name, G if name in ("plot", "measure", "control", "view", "merge") else D, param.opts[0], "1", opt, "2")
    add("control", G, "--sigma", "y0=0.002", "--sigma", "y0=0.004")
    add("control", G, "--sigma", "omega0=0.5", "--sigma", " omega0=0.6")
    add("roll", f"{C}/table1.toml", "--set", "initial.y0=0.2", "--set", "initial.y0=0.3")
    add("roll", f"{C}/table1.toml", "--set", "initial.y0=0.2", "--set", "initial . y0=0.3")
    add("sweep", f"{C}/demo.toml", "-o", str(W/"twice_set.h5"), "--set", "grid.x.num=8", "--set", "grid.x.num=9", out=W/"twice_set.h5")
    add("sweep", f"{C}/demo.toml", "-o", str(W/"twice_tab.h5"), "--set", "grid.x.num=8", "--set", "grid.x={param='y0', min=0.1, max=0.2, num=4}", out=W/"twice_tab.h5")
    add("simulate-drops", f"{C}/square_drops.toml", "-o", str(W/"twice_r.csv"), "--tracks", "3", "--range", "y0=0.1:0.2", "--range", "y0=0.2:0.3", out=W/"twice_r.csv")
    add("fit", D, "--config", f"{C}/square_drops.toml", "--effects", "air_drag,air_drag", "--json", str(W/"twice_e.json"), out=W/"twice_e.json")
    for sides in ("128", "1000", "2"):  # the README said 3 to 1000; the config takes 3 to 127
        add("roll", f"{C}/table1.toml", "--set", f"die.sides={sides}")
        add("sweep", f"{C}/demo.toml", "-o", str(W/f"sides{sides}.h5"), "--set", f"die.sides={sides}", out=W/f"sides{sides}.h5")
issue32_repeats_and_readme_cases()
def run(case):
    args, out = case
    env = dict(os.environ, DICE_SWEEP_COMPILE_NOTE="0")
    r = subprocess.run(["dice-sweep", *args], capture_output=True, text=True, env=env, timeout=600)
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    problems = []
    if r.returncode != 2: problems.append(f"rc={r.returncode}")
    if "Traceback" in r.stderr: problems.append("traceback")
    if len(lines) != 1: problems.append(f"{len(lines)} stderr lines")
    elif not lines[0].startswith("error:"): problems.append("no error: prefix")
    if out is not None and Path(out).exists(): problems.append("output left")
    return args, problems, (lines[-1] if lines else r.stdout.strip()[-200:])
with ThreadPoolExecutor(2) as ex:
    res = list(ex.map(run, cases))
bad = [r for r in res if r[1]]
for args, problems, last in bad:
    print(" ".join(a.replace(str(W)+"/", "W/").replace(C+"/","C/").replace(str(T) + "/", "T/") for a in args), "=>", problems, "|", last[:200])
print(f"{len(res) - len(bad)} of {len(res)} meet the rule")
shutil.rmtree(T, ignore_errors=True)
sys.exit(1 if bad else 0)
