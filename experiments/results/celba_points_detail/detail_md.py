import csv, sys, math, statistics as st
T95=[12.706,4.303,3.182,2.776,2.571,2.447,2.365,2.306,2.262,2.228,2.201,2.179,2.160]
def ci(v):
    n=len(v); m=st.mean(v)
    if n<2: return m,float('nan')
    return m,(T95[n-2] if n-2<len(T95) else 1.96)*st.stdev(v)/math.sqrt(n)
rows=list(csv.DictReader(open(sys.argv[1]))); mode=sys.argv[2]
f=lambda r,k: float(r[k]) if r[k]!='' else float('nan')
def parse(l): a=l.split(); return a[0],a[1],a[2]
g={}
for r in rows:
    k,d,res=parse(r['setting']); g.setdefault((r['camera'],res,k,d),[]).append(r)
dets=['extra-high','high','normal','low','extra-low']
cams=list(dict.fromkeys(r['camera'] for r in rows)); ress=list(dict.fromkeys(parse(r['setting'])[2] for r in rows))
m=lambda rr,k: st.mean([f(r,k) for r in rr if not math.isnan(f(r,k))])
def dd(p,b,k):
    v=[1e4*(f(a,k)-f(c,k)) for a,c in zip(p,b) if not(math.isnan(f(a,k)) or math.isnan(f(c,k)))]
    mm,h=ci(v)
    if mm==0 and h==0: return "0"
    return f"{mm:+.1f} ± {h:.1f}"+('' if abs(mm)>h else ' (noise)')
if mode=='full':
    print("| path | size | setting | triangles: points / billboards | points drawn | nodes walked | frame ms: points / billboards | Δ LOD error | Δ total error | Δ temporal error |")
    print("|---|---|---|--:|--:|--:|--:|--:|--:|--:|")
    for c in cams:
      for res in ress:
        for d in dets:
            p=g[(c,res,'points',d)]; b=g[(c,res,'billboards',d)]
            print(f"| {c} | {res} | {d} | {m(p,'triangles'):,.0f} / {m(b,'triangles'):,.0f} | {m(p,'points_drawn'):,.0f} | {m(p,'batches_tested'):.0f} | {1e3*m(p,'frame_s'):.0f} / {1e3*m(b,'frame_s'):.0f} | {dd(p,b,'lod_flip_mean')} | {dd(p,b,'total_flip_mean')} | {dd(p,b,'temporal_mean')} |")
else:
    print("| path | size | points: frame EH / H | points: triangles EH / H | billboards: frame EH / H | billboards: triangles EH / H |")
    print("|---|---|--:|--:|--:|--:|")
    for c in cams:
      for res in ress:
        cells=[]
        for kind in ['points','billboards']:
            eh=g[(c,res,kind,'extra-high')]; h=g[(c,res,kind,'high')]
            mm,hh=ci([f(a,'frame_s')/f(b,'frame_s') for a,b in zip(eh,h)])
            cells += [f"{mm:.2f} ± {hh:.2f}", f"{m(eh,'triangles')/m(h,'triangles'):.2f}"]
        print(f"| {c} | {res} | "+" | ".join(cells)+" |")
