# Triangles (points: solid, billboards: dashed) per Table 5.2 setting, one panel per path, one
# colour per resolution: a plain SVG (no plotting library on this machine).
import csv, sys, statistics as st
rows=list(csv.DictReader(open(sys.argv[1]))); out=sys.argv[2]
dets=['extra-high','high','normal','low','extra-low']
f=lambda r,k: float(r[k])
def parse(l): a=l.split(); return a[0],a[1],a[2]
cams=list(dict.fromkeys(r['camera'] for r in rows)); ress=list(dict.fromkeys(parse(r['setting'])[2] for r in rows))
val={}
for r in rows:
    k,d,res=parse(r['setting']); val.setdefault((r['camera'],res,k,d),[]).append(f(r,'triangles'))
mean={k:st.mean(v) for k,v in val.items()}
ymax=max(mean.values())*1.1
cols=['#0072b2','#d55e00','#009e73']
W,H,pw,ph,ml,mt=900,420,360,300,70,50
s=[f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">','<rect width="100%" height="100%" fill="white"/>',
   f'<text x="{W/2}" y="20" text-anchor="middle" font-size="14">celba_points_detail: tree triangles per Table 5.2 setting (points solid, billboards dashed)</text>']
for ci,c in enumerate(cams):
    x0=ml+ci*(pw+80); y0=mt
    s.append(f'<rect x="{x0}" y="{y0}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>')
    s.append(f'<text x="{x0+pw/2}" y="{y0-8}" text-anchor="middle">{c}</text>')
    for t in range(0,6):
        v=ymax*t/5; y=y0+ph-ph*t/5
        s.append(f'<line x1="{x0}" x2="{x0+pw}" y1="{y}" y2="{y}" stroke="#ddd"/><text x="{x0-5}" y="{y+4}" text-anchor="end">{v/1000:.0f}k</text>')
    X=lambda i: x0+pw*(i+0.5)/len(dets)
    for i,d in enumerate(dets): s.append(f'<text x="{X(i)}" y="{y0+ph+16}" text-anchor="middle">{d}</text>')
    for ri,res in enumerate(ress):
        for kind,dash in [('points',''),('billboards',' stroke-dasharray="5,4"')]:
            pts=' '.join(f'{X(i):.1f},{y0+ph-ph*mean[(c,res,kind,d)]/ymax:.1f}' for i,d in enumerate(dets))
            s.append(f'<polyline points="{pts}" fill="none" stroke="{cols[ri]}" stroke-width="2"{dash}/>')
            for i,d in enumerate(dets):
                s.append(f'<circle cx="{X(i):.1f}" cy="{y0+ph-ph*mean[(c,res,kind,d)]/ymax:.1f}" r="3" fill="{cols[ri]}"/>')
for ri,res in enumerate(ress):
    s.append(f'<line x1="{ml+ri*150}" x2="{ml+ri*150+30}" y1="{H-20}" y2="{H-20}" stroke="{cols[ri]}" stroke-width="2"/><text x="{ml+ri*150+36}" y="{H-16}">{res}</text>')
s.append('</svg>')
open(out,'w').write('\n'.join(s))
