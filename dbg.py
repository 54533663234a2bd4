import sys, numpy as np
from example_pcl import auto_finder as af, scene as sc, scene_objects as so, transforms, can_search as cs
case, seed = sys.argv[1], int(sys.argv[2])
scene = sc.generate_scene(so.case_spec(case, seed))
T = np.asarray(scene.truth["camera_from_table"]); to_plane = transforms.invert(T)
for t in scene.truth["objects"]:
    p = transforms.apply(to_plane, t["base_center"])
    print("truth", t.get("kind", t.get("type")), "can" if t["is_can"] else "", "r", round(t["radius"]*1000,1) if t.get("radius") else None, "h", round(t["height"]*1000), "base", p.round(4))
orig = cs.verify
def v(free, cx, cy, r, ctx):
    out = orig(free, cx, cy, r, ctx)
    can, reason, claim = out
    print(f"  verify hyp ({cx*1000:.1f},{cy*1000:.1f}) r {r*1000:.1f} n_free {len(free.idx)} -> " + (f"CAN r {can.radius*1000:.1f} at {np.round(can.center_plane*1000,1)} h {can.height*1000:.0f}" if can else f"{reason} claim {None if claim is None else len(claim)}"))
    return out
cs.verify = v
ob = cs.best_circles
def b(xy, cx, cy, r, eps, count, sensor=None, max_overlap=0.5):
    out = ob(xy, cx, cy, r, eps, count, sensor, max_overlap)
    print(" round: pool", len(xy), "hyps", len(cx), "best", [(round(a*1000,1), round(bb*1000,1), round(c*1000,1), n) for a,bb,c,n in out])
    return out
cs.best_circles = b
res = af.find_cans(scene.xyz)
for c in res.cans: print("FOUND", c.radius, c.center_plane, c.height, c.lying)
for r in res.rejected: print("REJ", r.reason)
