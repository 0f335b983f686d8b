#!/usr/bin/env python3
"""orbfix's int8 network vs TensorFlow Lite Micro's reference interpreter, byte for byte.

Used by scripts/tflm-check.sh (which builds the inputs and the model); see docs/interop.md.

  tflm_check.py inputs --real REAL.npy --random N --seed S --out INPUTS.npy
      REAL.npy (int8 [R, 64, 64, 1], `orbfix prepare-inputs`) followed by N random int8
      inputs: half uniform over -128..127, half normal with the core's scale (32 units per
      standard deviation) clipped to int8.
  tflm_check.py compare --model M.tflite --inputs INPUTS.npy --orbfix EMB.npy
      runs every input through TFLM, compares its int8 output (flattened NHWC) with the
      matching row of EMB.npy (`orbfix embed`), prints "N passed, M failed" and exits 1 on
      any mismatch.
"""

import argparse
import sys

import numpy as np


def make_inputs(args):
    real = np.load(args.real)
    if real.dtype != np.int8 or real.ndim != 4 or real.shape[1:] != (64, 64, 1):
        sys.exit(f"{args.real}: expected int8 [R, 64, 64, 1], got {real.dtype} {real.shape}")
    rng = np.random.default_rng(args.seed)
    half = args.random // 2
    uniform = rng.integers(-128, 128, size=(half, 64, 64, 1), dtype=np.int16)
    normal = np.clip(np.rint(rng.normal(0.0, 32.0, size=(args.random - half, 64, 64, 1))), -128, 127)
    batch = np.concatenate([real, uniform.astype(np.int8), normal.astype(np.int8)])
    np.save(args.out, batch)
    print(f"{args.out}: {len(real)} real + {args.random} random inputs")


def compare(args):
    from tflite_micro import runtime

    x = np.load(args.inputs)
    ours = np.load(args.orbfix)
    if ours.dtype != np.int8 or ours.ndim != 2 or len(ours) != len(x):
        sys.exit(f"{args.orbfix}: expected int8 [{len(x)}, D], got {ours.dtype} {ours.shape}")
    with open(args.model, "rb") as f:
        model = f.read()
    interp = runtime.Interpreter.from_bytes(model)
    inp = interp.get_input_details(0)
    out = interp.get_output_details(0)
    if inp["dtype"] != np.int8 or out["dtype"] != np.int8:
        sys.exit(f"{args.model}: input/output are not int8 ({inp['dtype']}, {out['dtype']})")
    passed = failed = values = 0
    for i in range(len(x)):
        interp.set_input(x[i : i + 1], 0)
        interp.invoke()
        y = interp.get_output(0).reshape(-1)
        if y.shape != ours[i].shape:
            sys.exit(f"output {i}: TFLM gives {y.size} values, orbfix {ours[i].size}")
        diff = np.count_nonzero(y != ours[i])
        if diff == 0:
            passed += 1
        else:
            failed += 1
            values += diff
            if failed <= 5:
                worst = int(np.max(np.abs(y.astype(np.int16) - ours[i].astype(np.int16))))
                print(f"input {i}: {diff} of {y.size} values differ (max |diff| {worst})")
    if failed:
        print(f"{values} differing values in {failed} embeddings")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("inputs")
    a.add_argument("--real", required=True)
    a.add_argument("--random", type=int, required=True)
    a.add_argument("--seed", type=int, default=1)
    a.add_argument("--out", required=True)
    c = sub.add_parser("compare")
    c.add_argument("--model", required=True)
    c.add_argument("--inputs", required=True)
    c.add_argument("--orbfix", required=True)
    args = p.parse_args()
    if args.cmd == "inputs":
        make_inputs(args)
        return 0
    return compare(args)


if __name__ == "__main__":
    sys.exit(main())
