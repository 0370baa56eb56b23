import csv, sys, collections
rows = list(csv.DictReader(open(sys.argv[1])))
def grp(r):
    p = r['path']
    return (r['scene'], r['size'], p.replace('camera360-','360-'))
G = collections.OrderedDict()
for r in rows:
    k = grp(r) + (r['variant'], r['occlusion'], r['order'])
    G.setdefault(k, []).append(r)
def mean(rs, f): return sum(float(x[f]) for x in rs)/len(rs)
print("| scene | path | variant | occlusion | order | frames | frame s | trees drawn | triangles | fragments shaded | overdraw | occluded | early | ties px | frags vs Veg off | tris vs Veg off |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for k, rs in G.items():
    scene, size, path, var, occ, order = k
    veg = G.get((scene, size, path, 'vegetation', 'off', 'exact'))
    fr = mean(veg,'fragments_shaded')/mean(rs,'fragments_shaded') if veg else 0
    tr = mean(veg,'triangles')/mean(rs,'triangles') if veg else 0
    print(f"| {scene} | {path} | {var} | {occ} | {order if occ!='off' else ''} | {len(rs)} | {mean(rs,'frame_s'):.2f} | {mean(rs,'trees_drawn'):,.0f} | {mean(rs,'triangles'):,.0f} | {mean(rs,'fragments_shaded'):,.0f} | {mean(rs,'overdraw'):.2f} | {mean(rs,'occluded'):,.0f} | {mean(rs,'early'):,.0f} | {sum(int(x['tie_px']) for x in rs)} | {fr:.2f} | {tr:.2f} |")
fc = sum(int(r['false_cull_px']) for r in rows)
print(f"\nframes: {len(rows)}, false-cull pixels over all: {fc}, exact-order differing pixels: {sum(int(r['differing_px']) for r in rows if r['order']=='exact')}, reorder tie pixels: {sum(int(r['tie_px']) for r in rows if r['order']=='reorder')} in {sum(1 for r in rows if r['order']=='reorder' and int(r['tie_px'])>0)} frames")
