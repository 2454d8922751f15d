"""What the run key costs per message: encode/decode with and without the HMAC-SHA256 envelope.

    python benchmarks/mac.py [--rules 48] [--n 20000]

Times coevo's own codec (``coevo.bus.messages.encode``/``decode``, pydantic validation
included) on a policy of ``--rules`` rules and on a status heartbeat, open and sealed,
and the HMAC alone; prints microseconds per message (best of 5 rounds of ``--n``).
"""

from __future__ import annotations

import argparse
import json
import time
import timeit

import numpy as np

from coevo.bus import keys
from coevo.bus.auth import RunKey, mac
from coevo.bus.messages import PolicyUpdate, Status, decode, encode
from coevo.policy import random_ruleset


def per_call_us(fn, n: int) -> float:
    return min(timeit.repeat(fn, number=n, repeat=5)) / n * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rules", type=int, default=48)
    ap.add_argument("--n", type=int, default=20000)
    args = ap.parse_args()
    secret = RunKey.create("bench").secret
    rules = random_ruleset("tracking", args.rules, np.random.default_rng(0)).to_dict()
    policy = PolicyUpdate(run="bench", behaviour="tracking", worker="tracking-0", version=3, generation=7, fitness=0.5,
                          episodes=90, rules=rules, sent_at=time.time())
    status = Status(run="bench", behaviour="tracking", worker="tracking-0", regime="mutual", generation=7, generations=50,
                    best_fitness=0.5, partner_versions={"docking": 2}, sent_at=time.time())
    out = {}
    for name, msg, key in (("policy", policy, keys.policy("bench", "tracking")),
                           ("status", status, keys.status("bench", "tracking", "tracking-0"))):
        plain, sealed = encode(msg), encode(msg, key=key, secret=secret)
        row = {
            "bytes": len(plain), "sealed_bytes": len(sealed),
            "hmac_us": per_call_us(lambda: mac(secret, key, plain), args.n),
            "encode_us": per_call_us(lambda: encode(msg), args.n // 10),
            "encode_sealed_us": per_call_us(lambda: encode(msg, key=key, secret=secret), args.n // 10),
            "decode_us": per_call_us(lambda: decode(plain, key=key), args.n // 10),
            "decode_verified_us": per_call_us(lambda: decode(sealed, key=key, secret=secret), args.n // 10),
        }
        row["encode_overhead_us"] = row["encode_sealed_us"] - row["encode_us"]
        row["decode_overhead_us"] = row["decode_verified_us"] - row["decode_us"]
        out[name] = {k: round(v, 2) for k, v in row.items()}
    for name, row in out.items():
        print(f"{name:7s} {row['bytes']:6d} B (+{row['sealed_bytes'] - row['bytes']} sealed): HMAC {row['hmac_us']:.1f} µs; "
              f"encode {row['encode_us']:.1f} -> {row['encode_sealed_us']:.1f} µs, "
              f"decode {row['decode_us']:.1f} -> {row['decode_verified_us']:.1f} µs")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
