#!/usr/bin/env python3
"""Checks that Cargo.toml's rust-version is honest about the dependencies: no crate scenebake
builds on Linux (normal and build dependencies, features as resolved) declares a newer
rust-version. (Clippy's incompatible_msrv lint checks our own use of the standard library
against the same rust-version.) Run from the repository root; exits 1 with the offenders."""
import json,subprocess,sys
out=subprocess.run(['cargo','metadata','--format-version','1','--locked','--filter-platform','x86_64-unknown-linux-gnu'],capture_output=True,text=True,check=True).stdout
m=json.loads(out)
nodes={n['id']:n for n in m['resolve']['nodes']}
pk={p['id']:p for p in m['packages']}
root=m['resolve']['root']
stack=[root]; seen=set()
while stack:
    i=stack.pop()
    if i in seen: continue
    seen.add(i)
    for d in nodes[i]['deps']:
        if any(k['kind'] in (None,'build') for k in d['dep_kinds']): stack.append(d['pkg'])
ver=lambda s: tuple((list(map(int, (s or '0').split('.'))) + [0, 0])[:3])
ours=pk[root]['rust_version']
worst=sorted(((ver(pk[i]['rust_version']),pk[i]['name'],pk[i]['version'],pk[i]['rust_version']) for i in seen if i!=root),reverse=True)
newer=[w for w in worst if w[0]>ver(ours)]
if newer:
    for w in newer:
        print(f"error: {w[1]} {w[2]} needs Rust {w[3]}, but Cargo.toml says rust-version = {ours}")
    sys.exit(1)
print(f"rust-version {ours}: every dependency agrees (newest: {worst[0][1]} {worst[0][2]} needs {worst[0][3]})")
