import csv, statistics as st, sys, math
r=list(csv.DictReader(open(sys.argv[1])))
def f(x,k):
    v=x.get(k,'')
    return float(v) if v not in ('',None) else 0.0
def ci(vals):
    if len(vals)<2: return 0
    return 1.96*st.stdev(vals)/math.sqrt(len(vals))
settings=['no impostors','impostors refresh 1','impostors refresh 4','impostors refresh 16','meshes only','meshes + impostors refresh 4']
base={'no impostors':'no impostors','impostors refresh 1':'no impostors','impostors refresh 4':'no impostors','impostors refresh 16':'no impostors','meshes only':'meshes only','meshes + impostors refresh 4':'meshes only'}
for scene in sorted(set(x['scene'] for x in r)):
  for cam in ['walkthrough','flight']:
      print(f"### {scene} {cam}")
      print("| setting | frame ms | impostor step ms | frame + step ms | Δ(frame+step) vs base ms | tiles/frame | held | triangles | tile triangles/frame | fragments | commands | LOD error | Δ LOD error | temporal | Δ temporal | trees needing mesh in an impostor |")
      print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
      for s in settings:
          rows=sorted([x for x in r if x['scene']==scene and x['camera']==cam and x['setting']==s], key=lambda x:int(x['frame']))
          b=sorted([x for x in r if x['scene']==scene and x['camera']==cam and x['setting']==base[s]], key=lambda x:int(x['frame']))
          m=lambda k: st.mean(f(x,k) for x in rows)
          tot=[f(x,'frame_s')+f(x,'impostor_s') for x in rows]
          btot=[f(x,'frame_s')+f(x,'impostor_s') for x in b]
          d=[a-c for a,c in zip(tot,btot)]
          dl=[f(a,'lod_flip_mean')-f(c,'lod_flip_mean') for a,c in zip(rows,b)]
          dt=[f(a,'temporal_mean')-f(c,'temporal_mean') for a,c in zip(rows[1:],b[1:])]
          temp=st.mean(f(x,'temporal_mean') for x in rows[1:])
          print(f"| {s} | {m('frame_s')*1000:.1f} | {m('impostor_s')*1000:.1f} | {st.mean(tot)*1000:.1f} | {st.mean(d)*1000:+.1f} ± {ci(d)*1000:.1f} | {m('tiles_rendered'):.1f} | {m('impostors_held'):.1f} | {m('triangles'):,.0f} | {m('tile_triangles'):,.0f} | {m('fragments'):,.0f} | {m('commands'):.0f} | {m('lod_flip_mean'):.4f} | {st.mean(dl):+.4f} ± {ci(dl):.4f} | {temp:.4f} | {st.mean(dt):+.4f} ± {ci(dt):.4f} | {m('trees_missing_lod'):.0f} |")
