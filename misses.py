import sys, numpy as np
from example_pcl import auto_finder as af, scene as sc, scene_objects as so, transforms
cases = sys.argv[1].split(",")
seeds = range(int(sys.argv[2]), int(sys.argv[3]))
for case in cases:
    tot = miss = false = 0
    for seed in seeds:
        scene = sc.generate_scene(so.case_spec(case, seed))
        T = np.asarray(scene.truth["camera_from_table"]); to_plane = transforms.invert(T)
        res = af.find_cans(scene.xyz)
        found = [transforms.apply(to_plane, c.base_center) for c in res.cans if not c.lying]
        for t in scene.truth["objects"]:
            if not t["is_can"]: continue
            tot += 1
            p = transforms.apply(to_plane, t["base_center"])
            d = [np.linalg.norm(f[:2]-p[:2]) for f in found]
            if not d or min(d) > max(0.015, 0.5*t["radius"]):
                miss += 1
                print(f"MISS {case} seed {seed}: r {t['radius']*1000:.1f} h {t['height']*1000:.0f} at {p.round(3)} support {t.get('support')}")
                for r in res.rejected:
                    print("    rejected:", r)
        # false
        nf = len(found) - sum(1 for t in scene.truth["objects"] if t["is_can"])
    print(case, "total", tot, "missed", miss)
