#!/usr/bin/env python3
"""Differing pixels of each hierarchy's frame against the grid's in a hierarchy_paths sweep folder (colour / LOD image), per kept pose.
usage: imgdiff.py SWEEP_DIR SCENE (needs `convert FILE.png ppm:-`)"""
import subprocess, sys, glob, os
def ppm(f):
    b=subprocess.run(['convert',f,'ppm:-'],capture_output=True).stdout
    parts=b.split(b'\n',3); w,h=map(int,parts[1].split()); return w,parts[3]
d=sys.argv[1]; scene=sys.argv[2]
for pose in sorted({os.path.basename(f).split('_ours')[0] for f in glob.glob(f'{d}/img/{scene}_*_ours_*_color.png')}):
    out=[]
    for h in ['grid-aabb','quadtree','octree','octree-euclidean','kmeans']:
        r=[]
        for s in ['color','lod']:
            f=lambda hh: f'{d}/img/{pose}_ours_gpu_default_hierarchy_{hh}_{s}.png'
            if not os.path.exists(f(h)): f=lambda hh: f'{d}/img/{pose}_ours_reference_default_hierarchy_{hh}_{s}.png'
            w,a=ppm(f('grid')); _,b=ppm(f(h))
            r.append(sum(1 for i in range(0,len(a),3) if a[i:i+3]!=b[i:i+3]))
        out.append(f'{h} {r[0]}/{r[1]}')
    print(pose, ' | '.join(out))
