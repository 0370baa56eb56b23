import csv, sys, math, statistics as st
T95=[12.706,4.303,3.182,2.776,2.571,2.447,2.365,2.306,2.262,2.228,2.201,2.179,2.160]
def ci(v):
    n=len(v); m=st.mean(v)
    if n<2: return m,float('nan')
    return m,(T95[n-2] if n-2<len(T95) else 1.96)*st.stdev(v)/math.sqrt(n)
rows=list(csv.DictReader(open(sys.argv[1])))
base='billboards (default)'
f=lambda r,k: float(r[k]) if r[k]!='' else float('nan')
by={(r['setting'],float(r['distance_m'])):r for r in rows}
settings=list(dict.fromkeys(r['setting'] for r in rows))
print("| band | setting | triangles | fragments | points | LOD error | Δ LOD | total error | Δ total | Δ total coverage | temporal | Δ temporal |")
print("|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
for lo,hi,name in [(1000,2000,'1-2 km'),(2000,3000,'2-3 km'),(3000,4001,'3-4 km')]:
    ds=sorted({d for (_,d) in by if lo<=d<hi}); b=[by[(base,d)] for d in ds]
    for s in settings:
        x=[by[(s,d)] for d in ds]
        def m(k): 
            v=[f(r,k) for r in x if not math.isnan(f(r,k))]; return st.mean(v)
        def d(k):
            v=[1e4*(f(a,k)-f(c,k)) for a,c in zip(x,b) if not (math.isnan(f(a,k)) or math.isnan(f(c,k)))]
            mm,h=ci(v)
            flag='' if abs(mm)>h else ' (noise)'
            return f"{mm:+.1f} ± {h:.1f}{flag}"
        if s==base:
            print(f"| {name} | **{s}** | {m('triangles'):,.0f} | {m('fragments'):,.0f} | 0 | {1e4*m('lod_flip_mean'):.1f} | | {1e4*m('total_flip_mean'):.1f} | | | {1e4*m('temporal_mean'):.1f} | |")
        else:
            print(f"| {name} | {s.replace('points ','')} | {m('triangles'):,.0f} | {m('fragments'):,.0f} | {m('points_drawn'):,.0f} | {1e4*m('lod_flip_mean'):.1f} | {d('lod_flip_mean')} | {1e4*m('total_flip_mean'):.1f} | {d('total_flip_mean')} | {d('total_coverage_error')} | {1e4*m('temporal_mean'):.1f} | {d('temporal_mean')} |")
    print(f"| {name} | *truth's tree pixels* | | | | | | | | {100*st.mean(f(r,'gt_tree_fraction') for r in b):.2f} % of the frame | | |")
