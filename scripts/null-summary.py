#!/usr/bin/env python3
# Summary of one scripts/bench-null.sh run: innocent trials per p threshold and statistic, false
# attributions with a 95 % upper bound, and the machine-readable record (OUT_JSON) that detection
# evidence packages quote. Usage: null-summary.py RUN_DIR SETUP_HOME MESHMARK OUT_JSON
import json, math, subprocess, sys
run, home, mm, out = sys.argv[1:5]
dets = json.load(open(run + "/detections.json"))
customers = {c["id"]: c["name"] for c in json.loads(subprocess.check_output([mm, "customer", "list", "--home", home, "--json"]))}
copies = json.load(open(run + "/copies.json"))
copy_customer = {c["id"]: customers.get(c["customer_id"], c.get("customer")) for c in copies}
ln10 = math.log(10)
trials, leaks = [], []
for d in dets:
    stem, kind, truth = d["suspect_name"].rsplit(".", 1)[0].split("--")
    tried = d["details"].get("copies_tried", 0)
    for cand in d["details"].get("candidates", []):
        for s in cand["copies"]:
            who = copy_customer.get(s["copy_id"])
            row = (s["sign_neg_log10_p"], s["matched_neg_log10_p"], -math.log10(max(s["p_value"], 1e-300)), kind[-1])
            (leaks if who == truth else trials).append(row)
n = len(trials)
print("innocent trials: %d (suspect, copy) pairs over %d detections; %d leaked-copy scores besides" % (n, len(dets), len(leaks)))
print()
print("%-10s %12s %12s %12s %12s" % ("p below", "expected", "sign count", "matched", "combined"))
for alpha in (0.1, 0.01, 0.001, 1e-4, 1e-6, 1e-9):
    t = -math.log10(alpha)
    counts = [sum(r[i] > t for r in trials) for i in range(3)]
    print("%-10g %12.1f %12d %12d %12d" % (alpha, alpha * n, *counts))
# One source under its six attacks keeps much of its recovered pattern and meets the same copies'
# keys, so its trials are not independent across attacks; within one attack they are.
print()
print("per attack (independent trials within each): below 0.01 / below 0.001, sign count | matched | combined")
for k in sorted({r[3] for r in trials}):
    rs = [r for r in trials if r[3] == k]
    cells = ["%d / %d" % (sum(r[i] > 2 for r in rs), sum(r[i] > 3 for r in rs)) for i in range(3)]
    print("attack %s: %4d trials, expected %.1f / %.2f:  %s | %s | %s" % (k, len(rs), 0.01 * len(rs), 0.001 * len(rs), *cells))
false = 0
for d in dets:
    stem, kind, truth = d["suspect_name"].rsplit(".", 1)[0].split("--")
    for a in d["details"].get("attributed", []):
        if customers.get(a["customer_id"]) != truth:
            false += 1
bound = 1 - 0.05 ** (1.0 / n) if false == 0 and n else float("nan")
print()
print("false attributions (corrected p < threshold, a copy not in the suspect): %d of %d trials" % (false, n))
if false == 0:
    print("95 %% upper confidence bound on the false-attribution rate per trial: %.2g (3/n rule %.2g)" % (bound, 3.0 / n))
print("largest innocent -log10 p: sign %.2f, matched %.2f, combined %.2f" % tuple(max(r[i] for r in trials) for i in range(3)))

# The record detection evidence quotes (compiled into meshmark): the measured false-attribution
# rate with its bound, and how it was measured.
commit = subprocess.run(["git", "-C", __import__("os").path.dirname(out), "describe", "--always", "--dirty"],
                        capture_output=True, text=True).stdout.strip() or "unknown"
record = {"trials": n, "detections": len(dets), "false_attributions": false,
          "upper_bound_95": bound if false == 0 else None,
          "largest_innocent_neg_log10_p": {"sign": max(r[0] for r in trials), "matched": max(r[1] for r in trials),
                                           "combined": max(r[2] for r in trials)},
          "suspects": "shared CAD parts protected for 12 customers; unmarked originals and one customer's copy, "
                      "each under 6 attacks (noise, smoothing, remeshing, simplification, quantisation, subdivision)",
          "command": "scripts/bench-null.sh", "commit": commit,
          "run": __import__("time").strftime("%Y-%m-%d %H:%M UTC", __import__("time").gmtime())}
with open(out + ".tmp", "w") as f:
    json.dump(record, f, indent=2)
    f.write("\n")
__import__("os").replace(out + ".tmp", out)
