"""The generated part of the bad-input table (tests/test_bad_inputs.py): every numeric, path and
choice option of every command with the values that must be refused (exit 2, one line naming the
option), model names and scenario fields beyond their bounds. Each entry: (class, argv, input
files, words the line must hold), the same shape as test_bad_inputs.CLI."""

from __future__ import annotations

S = ["--scenario", "{d}/in/s.toml"]
SMALL = "[scenario]\nduration = 1.0\nruns = 1\nmetrics_from = 0.2\nreferences = [\"seesaw\"]\n"
SF = {"s.toml": SMALL}
INT_BAD = ["abc", "1.5", ""]          # argparse: not an int
FLOAT_BAD = ["abc", "1,5", ""]        # argparse: not a float


def _opt(cls, cmd, flag, values, files=None, extra=(), words=None):
    out = {}
    for v in values:
        argv = [cmd, *extra, flag, v]
        out[f"{cmd} {flag} {v!r}"] = (cls, argv, dict(files or {}), [flag] if words is None else words)
    return out


def generated() -> dict:
    c = {}
    # --- build ---------------------------------------------------------------------------------
    c |= _opt("option: not a number", "build", "--max-lag", INT_BAD)
    c |= _opt("option: out of range", "build", "--max-lag", ["-1", "100000"])
    c |= _opt("option: not a number", "build", "--nodes", INT_BAD)
    c |= _opt("option: out of range", "build", "--nodes", ["0", "-2", "100000"])
    c |= _opt("option: not a number", "build", "--ts", FLOAT_BAD)
    c |= _opt("option: out of range", "build", "--ts", ["0", "-0.01", "inf", "-inf"])
    c |= _opt("option: not a number", "build", "--singular-rtol", FLOAT_BAD)
    c |= _opt("option: out of range", "build", "--singular-rtol", ["-1", "nan", "inf", "1"])
    c |= _opt("option: not a number", "build", "--gate", FLOAT_BAD)
    c |= _opt("option: out of range", "build", "--gate", ["0", "-3", "nan", "inf"])
    c |= _opt("option: not a number", "build", "--max-seconds", FLOAT_BAD)
    c |= _opt("option: out of range", "build", "--max-seconds", ["-1", "nan", "inf"])
    c |= _opt("option: not a number", "build", "--max-memory", FLOAT_BAD)
    c |= _opt("option: out of range", "build", "--max-memory", ["0", "-1", "nan"])
    c |= _opt("option: not a choice", "build", "--precision", ["half", "", "DOUBLE"])
    c |= _opt("option: not a choice", "build", "--oosm", ["discard", ""])
    c |= _opt("option: not a choice", "build", "--fusion", ["sum", ""])
    c |= _opt("output path", "build", "--out", ["", "/proc/x"], words=["--out"])
    # --- inspect -------------------------------------------------------------------------------
    c |= _opt("option: not a number", "inspect", "--ts", FLOAT_BAD)
    c |= _opt("option: out of range", "inspect", "--ts", ["0", "-1", "inf"])
    # --- simulate ------------------------------------------------------------------------------
    c |= _opt("option: not a number", "simulate", "--runs", INT_BAD, SF, S)
    c |= _opt("option: out of range", "simulate", "--runs", ["-1", "1000000000"], SF, S)
    c |= _opt("option: not a number", "simulate", "--seed", INT_BAD, SF, S)
    c |= _opt("option: out of range", "simulate", "--seed", ["-1", "4294967296"], SF, S)
    c["simulate --seed past the top"] = ("option: out of range", ["simulate", *S, "--seed", "4294967295", "--runs", "2"],
                                         SF, ["--seed 4294967295", "--runs 2", "4294967296"])
    c |= _opt("option: not a number", "simulate", "--nodes", INT_BAD, SF, S)
    c |= _opt("option: out of range", "simulate", "--nodes", ["0", "-1"], SF, S)
    c |= _opt("option: not a number", "simulate", "--max-lag", INT_BAD, SF, S)
    c |= _opt("option: out of range", "simulate", "--max-lag", ["0", "-3"], SF, S)
    c |= _opt("option: not a choice", "simulate", "--filters", ["kf", "df,pf", ","], SF, S)
    c |= _opt("option: not a choice", "simulate", "--engine", ["python", ""], SF, S)
    c |= _opt("option: not a choice", "simulate", "--reference", ["step", ""], SF, S)
    c |= _opt("option: not a choice", "simulate", "--oosm", ["x"], SF, S)
    c |= _opt("option: not a choice", "simulate", "--fusion", ["x"], SF, S)
    c |= _opt("option: not a number", "simulate", "--workers", INT_BAD, SF, S)
    c |= _opt("option: not an address", "simulate", "--scheduler", ["nonsense"], SF, S, words=["--scheduler", "nonsense"])
    for flag in ("--json", "--csv", "--results"):
        c |= _opt("output path", "simulate", flag, ["{d}/nodir/x.out", "{d}/user", "/proc/x.out",
                                                    "{d}/user/notes.txt/x.out"], SF, S)
    c["simulate --resume binary"] = ("input file", ["simulate", *S, "--resume", "{d}/in/r.jsonl"],
                                     {**SF, "r.jsonl": bytes(range(256))}, ["--resume", "r.jsonl"])
    c["simulate --resume missing"] = ("input file", ["simulate", *S, "--resume", "{d}/in/none.jsonl"], SF,
                                      ["--resume", "none.jsonl"])
    c["simulate --resume not records"] = ("input file", ["simulate", *S, "--resume", "{d}/in/r.jsonl"],
                                          {**SF, "r.jsonl": "hello\nworld\n"}, ["--resume", "line 1"])
    # one line, not a record: it used to pass as a torn record, then be cut (no newline) or appended to
    c["simulate --resume one line of text"] = ("input file", ["simulate", *S, "--resume", "{d}/in/r.jsonl"],
                                               {**SF, "r.jsonl": "IMPORTANT DATA"}, ["--resume", "line 1"])
    c["simulate --resume a --json file"] = ("input file", ["simulate", *S, "--resume", "{d}/in/r.json"],
                                            {**SF, "r.json": '{"settings": {}, "tables": []}\n'},
                                            ["--resume", "line 1"])
    c["simulate --resume folder"] = ("input file", ["simulate", *S, "--resume", "{d}/user"], SF, ["--resume"])
    for name, text, words in (
            ("runs 1e9", SMALL.replace("runs = 1", "runs = 1000000000"), ["scenario.runs", "at most"]),
            ("harmonics 1e9", SMALL + "[reference]\nharmonics = 1000000000\n", ["reference.harmonics", "at most"]),
            ("duration 0", SMALL.replace("1.0", "0.0", 1), ["scenario.duration"]),
            ("duration -1", SMALL.replace("1.0", "-1.0", 1), ["scenario.duration"]),
            ("runs 0", SMALL.replace("runs = 1", "runs = 0"), ["scenario.runs"]),
            ("runs 1.5", SMALL.replace("runs = 1", "runs = 1.5"), ["scenario.runs"]),
            ("ts 0", SMALL + "ts = 0.0\n", ["scenario.ts"]),
            ("one step", SMALL.replace("1.0", "0.015", 1).replace("0.2", "0.0"), ["scenario.duration", "1.5 steps"]),
            ("ts above duration", SMALL + "ts = 2.0\n", ["scenario.duration", "0.5 steps", "at least 2"]),
            ("period 1e-300", SMALL + "[reference]\nperiod = 1e-300\n", ["reference.period", "two sampling periods"]),
            ("substeps 1e9", SMALL + "substeps = 1000000000\n", ["scenario.substeps", "at most 1000"]),
            ("metrics_from 2", SMALL.replace("metrics_from = 0.2", "metrics_from = 2.0"), ["metrics_from"]),
            ("references typo", SMALL.replace('"seesaw"', '"seasaw"'), ["seasaw"]),
            ("nested 10000", "a = " + "[" * 10000 + "]" * 10000 + "\n", ["nested too deeply"]),
            ("malformed", "[scenario\n", ["malformed TOML"]),
            ("binary", b"\x00\x01\x02", ["s.toml"])):
        c[f"scenario {name}"] = ("scenario file", ["simulate", *S], {"s.toml": text}, ["s.toml", *words])
    # --- every numeric scenario field is finite (an inf ran, then diverged or crashed) -----------
    for name, table, words in (
            ("q inf", "[filter]\nq = [inf]", ["s.toml:7", "filter.q", "finite", "inf"]),
            ("p0_std inf", "[filter]\np0_std = [inf, 0.1, 1.0]", ["s.toml:7", "filter.p0_std", "finite"]),
            ("poles inf", "[control]\npoles = inf", ["s.toml:7", "control.poles", "finite"]),
            ("period inf", "[reference]\nperiod = inf", ["s.toml:7", "reference.period", "finite"]),
            ("cycles inf", "[reference]\ncycles = [inf]", ["s.toml:7", "reference.cycles", "finite"]),
            ("amplitude inf", "[reference]\namplitude = [inf]", ["s.toml:7", "reference.amplitude", "finite"]),
            ("phase inf", "[reference]\nphase = [inf]", ["s.toml:7", "reference.phase", "finite"]),
            ("offset -inf", "[reference]\noffset = [-inf]", ["s.toml:7", "reference.offset", "finite"]),
            ("tracking_bound inf", "[reference]\ntracking_bound = [inf]", ["s.toml:7", "reference.tracking_bound", "finite"]),
            ("harmonics 1e400", "[reference]\nharmonics = 1" + "0" * 400, ["s.toml:7", "reference.harmonics"]),
            ("noise_scale 1e-300", "[[nodes]]\nnoise_scale = 1e-300\n", ["nodes[1].noise_scale", "within [1e-100, 1e+100]"]),
            ("noise_std 1e-300", "[[nodes]]\nnoise_std = [1e-300]\n", ["nodes[1].noise_std", "within [1e-100"]),
            ("p0_std 1e300", "[filter]\np0_std = [1e300, 1, 1]\n", ["filter.p0_std", "within [1e-100"]),
            ("noise_scale inf", "[[nodes]]\nnoise_scale = inf\n[[nodes]]\nnoise_scale = 1.0",
             ["s.toml:7", "nodes[1].noise_scale", "finite"]),
            ("noise_std inf", "[[nodes]]\nnoise_scale = 1.0\nnoise_std = [1e-3, inf]\n[[nodes]]\nnoise_scale = 1.0",
             ["s.toml:8", "nodes[1].noise_std", "finite"]),
            ("uplink p_drop nan", "[uplink]\np_drop = nan", ["s.toml:7", "uplink.p_drop", "finite"]),
            ("gate 0", "[filter]\ngate = 0", ["s.toml:7", "filter.gate", "> 0"]),
            ("gate inf", "[filter]\ngate = inf", ["s.toml:7", "filter.gate", "finite"]),
            ("outliers 1", "[[nodes]]\noutliers = 1.0", ["s.toml:7", "nodes[1].outliers", "[0, 1)"]),
            ("outliers -0.1", "[[nodes]]\noutliers = -0.1", ["s.toml:7", "nodes[1].outliers", ">= 0"]),
            ("outlier_size 0", "[[nodes]]\noutliers = 0.1\noutlier_size = 0", ["nodes[1].outlier_size", "> 0"]),
            ("grid p inf", "[[grid]]\nd = 0\np = inf", ["s.toml:8", "grid[1].p", "finite"]),
            ("absolute offset zeroes L", "[model_error]\nabsolute = { L = -0.005 }",
             ["s.toml:7", "model_error.absolute.L", "zero or sign flip"]),
            ("absolute offset flips L", "[model_error]\nabsolute = { L = -0.01 }",
             ["s.toml:7", "model_error.absolute.L", "sign flip"]),
            ("absolute offset and spread flip L", "[model_error]\nabsolute = { L = -0.004 }\nspread = 0.5",
             ["s.toml:7", "model_error.absolute.L", "sign flip"])):
        c[f"scenario {name}"] = ("scenario field", ["simulate", *S, "--engine", "reference"],
                                 {"s.toml": SMALL + table + "\n"}, words)
    c["--param-error twice"] = ("option: out of range", ["simulate", *S, "--engine", "reference", "--param-error",
                                                         "R=0.1,R=0.2"], SF, ["--param-error", "R is given twice"])
    # --- inputs that are not regular files (read until memory ran out) -------------------------
    for cmd in ("inspect", "build", "simulate"):
        c[f"{cmd} model /dev/zero"] = ("model file", [cmd, "/dev/zero"], {}, ["/dev/zero", "not a regular file"])
    c["simulate scenario /dev/zero"] = ("scenario file", ["simulate", "--scenario", "/dev/zero"], {},
                                        ["/dev/zero", "scenario file", "not a regular file"])
    c["trajectory /dev/zero"] = ("trajectory file", ["simulate", *S],
                                 {"s.toml": SMALL + '[reference]\nfile = "/dev/zero"\n'},
                                 ["s.toml:7", "reference.file", "/dev/zero", "not a regular file"])
    # --- an output is never an input, nor a file another program wrote ---------------------------
    for flag in ("--json", "--csv", "--results"):
        c[f"simulate {flag} is the scenario"] = ("output path", ["simulate", *S, flag, "{d}/in/s.toml"], SF,
                                                 [flag, "s.toml", "is the scenario file this command reads"])
        c[f"simulate {flag} a user's file"] = ("output path", ["simulate", *S, flag, "{d}/user/notes.txt"], SF,
                                               [flag, "notes.txt", "exists and was not written by codegen simulate",
                                                "remove it or choose another path"])
    c["simulate --json is the model"] = ("output path", ["simulate", "{d}/in/m.toml", *S, "--json", "{d}/in/m.toml"],
                                         {**SF, "m.toml": ("name", "dc_motor_link")},
                                         ["--json", "m.toml", "is the model file"])
    c["simulate --csv is the trajectory"] = (
        "output path", ["simulate", *S, "--csv", "{d}/in/t.csv"],
        {"s.toml": SMALL.replace('references = ["seesaw"]\n', "") + '[reference]\nfile = "t.csv"\n',
         "t.csv": "t,theta\n" + "".join(f"{k * 0.01!r},{0.1 * k * 0.01!r}\n" for k in range(101))},
        ["--csv", "t.csv", "not written by codegen simulate"])   # a trajectory's first column is t, never --csv's
    c["simulate --json and --csv one file"] = ("output path", ["simulate", *S, "--json", "{d}/r.out", "--csv",
                                                               "{d}/r.out"], SF, ["--csv", "r.out", "also given to --json"])
    c["simulate --json a device"] = ("output path", ["simulate", *S, "--json", "/dev/null"], SF,
                                     ["--json", "/dev/null", "not a regular file"])
    c["bench --out a user's file"] = ("output path", ["bench", "--out", "{d}/user/notes.txt"], {},
                                      ["--out", "notes.txt", "not written by codegen bench"])
    c["bench --out is the model"] = ("output path", ["bench", "{d}/in/m.toml", "--out", "{d}/in/m.toml"],
                                     {"m.toml": ("name", "dc_motor_link")}, ["--out", "m.toml", "is the model file"])
    c["reproduce --doc a user's file"] = ("output path", ["reproduce", "--out", "{d}/rep", "--doc",
                                                          "{d}/user/notes.txt"], {},
                                          ["--doc", "notes.txt", "not written by codegen reproduce"])
    c["scenario --out is the model"] = ("output path", ["scenario", "{d}/in/m.toml", "--out", "{d}/in/m.toml"],
                                        {"m.toml": ("name", "dc_motor_link")}, ["--out", "m.toml", "is the model file"])
    c["scenario missing"] = ("scenario file", ["simulate", "--scenario", "{d}/in/none.toml"], {}, ["none.toml"])
    # --- a user's trajectory (experiment/trajectory_file.py): dc_motor_link's theta, 1 s at 10 ms ----
    traj = "[scenario]\nduration = 1.0\nruns = 1\nmetrics_from = 0.2\n[reference]\nfile = \"t.csv\"\n"
    rows = "".join(f"{k * 0.01!r},{0.1 * k * 0.01!r}\n" for k in range(101))
    for name, csv, words in (
            ("missing column", "t,phi\n" + rows, ["t.csv", "no column 'theta'"]),
            ("NaN", "t,theta\n" + rows.replace("0.02,0.002", "0.02,nan"), ["t.csv:4", "column theta", "finite"]),
            ("not a number", "t,theta\n" + rows.replace("0.02,0.002", "0.02,x"), ["t.csv:4", "column theta"]),
            ("time not increasing", "t,theta\n" + rows.replace("0.03,", "0.02,"), ["t.csv:5", "time must increase"]),
            ("one row", "t,theta\n0,0\n", ["t.csv", "at least 2"]),
            ("shorter than the run", "t,theta\n" + rows[:rows.index("0.5,")], ["t.csv:51", "shorter than the run"]),
            ("derivative missing", "t,theta,theta_d1\n" + rows.replace("\n", ",0\n"), ["t.csv", "theta_d2 missing"]),
            ("missing", None, ["t.csv"])):
        files = {"s.toml": traj} if csv is None else {"s.toml": traj, "t.csv": csv}
        c[f"trajectory {name}"] = ("trajectory file", ["simulate", *S], files, ["s.toml", "reference.file", *words])
    # a shape asked of a file-only scenario ran at the default amplitude 1, diverging, without a word
    c["simulate --reference sinusoid on a file-only scenario"] = (
        "trajectory file", ["simulate", *S, "--reference", "sinusoid"], {"s.toml": traj, "t.csv": "t,theta\n" + rows},
        ["--reference sinusoid", "s.toml", "file only", "amplitude"])
    c["scenario --trajectory missing"] = ("trajectory file", ["scenario", "--trajectory", "{d}/in/none.csv"], {},
                                          ["none.csv"])
    c |= _opt("option: out of range", "scenario", "--smoothing", ["-1", "nan"], {"t.csv": "t,theta\n" + rows},
              ["--trajectory", "{d}/in/t.csv"], ["--smoothing"])
    c |= _opt("option: not a number", "scenario", "--smoothing", FLOAT_BAD, None, ["--trajectory", "x.csv"])
    # --- network -------------------------------------------------------------------------------
    c |= _opt("option: not a number", "network", "--duration", FLOAT_BAD)
    c |= _opt("option: out of range", "network", "--duration", ["0", "-5", "nan", "1e9", "inf"])
    c |= _opt("option: not a number", "network", "--row", INT_BAD)
    c |= _opt("option: out of range", "network", "--row", ["-1", "99"])
    c |= _opt("option: out of range", "network", "--seed", ["-1", "4294967296"])
    c |= _opt("option: not a key", "network", "--key", ["abc", "00112233445566778899aabbccddeeXX", "0" * 34])
    c |= _opt("option: not a number", "network", "--flip-rate", FLOAT_BAD)
    c |= _opt("option: out of range", "network", "--flip-rate", ["1", "-0.1", "nan"])
    c |= _opt("output path", "network", "--keep", ["{d}/user/notes.txt", "/proc/x"])
    c |= _opt("option: not a choice", "network", "--precision", ["half"])
    c["network keep not empty"] = ("output path", ["network", "--keep", "{d}/user"], {}, ["--keep", "not empty"])
    # --- verify, scenario, bench -----------------------------------------------------------------
    c |= _opt("option: not a choice", "verify", "--target", ["m7", ""])
    c |= _opt("option: not a choice", "verify", "--precision", ["half"])
    c |= _opt("option: not a choice", "verify", "--inputs", ["mine"])
    c["verify scenario missing"] = ("scenario file", ["verify", "--scenario", "{d}/in/none.toml"], {}, ["none.toml"])
    c |= _opt("output path", "scenario", "--out", ["/proc/x.toml", "{d}/nodir/x.toml", "{d}/user",
                                                   "{d}/user/notes.txt"])
    # --- disturbance states: their densities and time constant, in a scenario or as options ----
    for label, table, words in [("negative density", 'kind = "random_walk"\nq = -1.0', ["disturbance.q", ">= 0"]),
                                ("tau 0", 'kind = "gauss_markov"\nq = 1.0\ntau = 0', ["disturbance.tau", "> 0"]),
                                ("tau < 0", 'kind = "gauss_markov"\nq = 1.0\ntau = -2.0', ["disturbance.tau"]),
                                ("no kind", "q = 1.0", ["disturbance.kind"]),
                                ("zero density without p0_std", 'kind = "random_walk"\nq = [0.0]',
                                 ["disturbance.p0_std", "disturbance.q", "is 0"]),
                                ("densities for another model", 'kind = "random_walk"\nq = [1.0, 2.0]',
                                 ["disturbance.q", "needs 1 value"]),
                                ("integrated walk's zero density without its rates' std",
                                 'kind = "integrated_random_walk"\nq = 0.0\np0_std = 1.0',
                                 ["disturbance.p0_std", "the d's, then their rates'"])]:
        c[f"scenario disturbance {label}"] = ("scenario field", ["simulate", *S, "--engine", "reference"],
                                              {"s.toml": SMALL + f"\n[disturbance]\n{table}\n"}, words)
    c["disturbance with the Brunovsky predictor"] = (
        "scenario field", ["simulate", *S, "--engine", "reference", "--predictor", "brunovsky"],
        {"s.toml": SMALL + '\n[disturbance]\nkind = "random_walk"\nq = 1.0\n'}, ["--predictor held"])
    c["verify disturbance with the Brunovsky predictor"] = (
        "scenario field", ["verify", *S, "--predictor", "brunovsky"],
        {"s.toml": SMALL + '\n[disturbance]\nkind = "random_walk"\nq = 1.0\n'}, ["s.toml:", "[disturbance]", "--predictor held"])
    c["network disturbance with retrodiction (its default predictor: Brunovsky)"] = (
        "scenario field", ["network", *S, "--oosm", "retrodict"],
        {"s.toml": SMALL + '\n[disturbance]\nkind = "random_walk"\nq = 1.0\n'}, ["s.toml:", "[disturbance]", "--oosm replay"])
    # --- parameter offsets of the comparison's `offsets` filter ---------------------------------
    for label, table, words in [("unknown parameter", 'params = ["R", "Rx"]', ["offsets.params", "Rx"]),
                                ("zero std", 'params = ["R"]\nstd = 0', ["offsets.std", "> 0"]),
                                ("negative density", 'params = ["R"]\nq = -1.0', ["offsets.q", ">= 0"])]:
        c[f"scenario offsets {label}"] = ("scenario field", ["simulate", *S, "--engine", "reference",
                                                             "--filters", "df,offsets"],
                                          {"s.toml": SMALL + f"\n[offsets]\n{table}\n"}, words)
    c["offsets filter without its table"] = ("scenario field", ["simulate", *S, "--engine", "reference",
                                                                "--filters", "df,offsets"],
                                             {"s.toml": SMALL}, ["--filters offsets", "[offsets]"])
    c |= _opt("option: not a choice", "build", "--disturbance", ["walk", ""], words=["--disturbance"])
    c["build disturbance with the Brunovsky predictor"] = (
        "option: not a choice", ["build", "--disturbance", "random_walk", "--predictor", "brunovsky"], {},
        ["--disturbance", "--predictor held"])
    c["build disturbance with retrodiction (its default predictor: Brunovsky)"] = (
        "option: not a choice", ["build", "--disturbance", "random_walk", "--oosm", "retrodict"], {},
        ["--disturbance", "--oosm replay", "held or scheduled"])
    c["build retrodiction with the scheduled predictor"] = (
        "option: not a choice", ["build", "--oosm", "retrodict", "--predictor", "scheduled"], {},
        ["--oosm retrodict", "--predictor brunovsky", "scheduled"])
    c["build tau without gauss_markov"] = ("option: out of range", ["build", "--tau", "0.5"], {},
                                           ["--tau", "gauss_markov"])
    c |= _opt("option: not a choice", "scenario", "--disturbance", ["walk", ""])
    # a period past the model's 1e5 steps (1e300 crashed allocating, 1e6 ran for hours) or under 2 Ts
    c |= _opt("option: out of range", "scenario", "--period", ["1e300", "1e6", "0.015"],
              words=["--period", "0.02 to 1000 s", "Ts = 0.01 s"])
    c |= _opt("option: out of range", "scenario", "--tau", ["0", "-1", "nan"], extra=("--disturbance", "gauss_markov"))
    for v in ("0", "nan"):     # auto takes a tau for its Gauss-Markov candidates: the same check
        c[f"scenario --disturbance auto --tau {v}"] = ("option: out of range",
                                                      ["scenario", "--disturbance", "auto", "--tau", v], {},
                                                      ["--tau", "auto"])
    c |= _opt("option: not a choice", "scenario", "--offsets", ["R"], extra=("--param-error", "0.2"),
              words=["--offsets", "--disturbance"])
    c |= _opt("option: not a choice", "scenario", "--offsets", ["Rx", "R,R", "R,"],
              extra=("--disturbance", "random_walk", "--param-error", "0.2"), words=["--offsets"])
    c |= _opt("option: not a choice", "scenario", "--offsets", ["m"],
              extra=("--disturbance", "random_walk", "--param-error", "R=0.1"), words=["--offsets", "m"])
    c |= _opt("option: not a number", "bench", "--repeat", INT_BAD)
    c |= _opt("option: out of range", "bench", "--repeat", ["-1", "100000"])
    c |= _opt("output path", "bench", "--out", ["/proc/B.md", "{d}/nodir/B.md", "{d}/user"])
    # --- model names ---------------------------------------------------------------------------
    names = ["ab_node", "x_master", "arm_lib", "robot_kern", "cam_internal", "unistd", "transport", "pthread",
             "common", "relay", "a b", "9lives", "ab-c", "V\\n", "_x"]
    for name in names:
        c[f"model named {name!r}"] = ("model name", ["build", "{d}/in/m.toml"], {"m.toml": ("name", name)},
                                      ["model.name"])
    # --- commands on missing or bad model files --------------------------------------------------
    for cmd in ("inspect", "simulate", "verify", "scenario", "network"):
        c[f"{cmd} missing model"] = ("model file", [cmd, "{d}/in/none.toml"], {}, ["none.toml"])
        c[f"{cmd} binary model"] = ("model file", [cmd, "{d}/in/m.toml"], {"m.toml": b"\x89PNG\x00"},
                                    ["m.toml"])
        c[f"{cmd} unknown built-in"] = ("model file", [cmd, "dc_motor"], {}, ["dc_motor"])
    return c
