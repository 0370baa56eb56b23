import csv, sys, statistics as st, collections
rows = list(csv.DictReader(open(sys.argv[1])))
g = collections.defaultdict(list)
for r in rows:
    key = (r['camera'], r['variant'], r['hierarchy'])
    g[key].append(r)
def mean(rs, c):
    v = [float(r[c]) for r in rs if r[c] not in ('', None)]
    return st.mean(v) if v else float('nan')
print("| camera | variant | hierarchy | frame ms | select ms | gpu select ms | gpu draw ms | nodes visited | commands | trees drawn | trees_outside_view | FLIP |")
print("|---|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
for key in sorted(g):
    rs = g[key]
    print(f"| {key[0]} | {key[1]} | {key[2]} | {1000*mean(rs,'frame_s'):.0f} | {1000*mean(rs,'select_s'):.1f} | {1000*mean(rs,'gpu_select_s'):.1f} | {1000*mean(rs,'gpu_draw_s'):.0f} | {mean(rs,'batches_tested'):.0f} | {mean(rs,'commands'):.0f} | {mean(rs,'trees_drawn'):.0f} | {mean(rs,'trees_outside_view'):.0f} | {mean(rs,'flip_mean'):.4f} |")
print()
# ratios: vegetation frame / ours frame, per camera and hierarchy, per-frame paired by (yaw)
print("| camera | hierarchy | Vegetation / ours (mean of per-yaw ratios) | trees_outside_view vs grid |")
print("|---|---|--:|--:|")
for cam in sorted({k[0] for k in g}):
    grid_out = mean(g[(cam,'ours','grid')], 'trees_outside_view')
    for h in ['grid','grid-aabb','quadtree','octree']:
        ours = g.get((cam,'ours',h)); veg = g.get((cam,'vegetation',h))
        if not ours or not veg: continue
        vy = {r['yaw_deg']: float(r['frame_s']) for r in veg}
        ratios = [vy[r['yaw_deg']]/float(r['frame_s']) for r in ours if r['yaw_deg'] in vy]
        out = mean(ours,'trees_outside_view')
        print(f"| {cam} | {h} | {st.mean(ratios):.2f}x ({', '.join(f'{x:.2f}' for x in ratios)}) | {out:.0f} ({out/grid_out if grid_out else float('nan'):.2f}x) |")
