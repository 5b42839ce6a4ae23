# Derives testdata/middlebury-line/SCENE/points_0246.txt from SCENE/disp1.png (numpy, Pillow):
# python3 make_points.py SCENE > SCENE/points_0246.txt (then prepend the comment line). Not run by tests.
import sys, numpy as np
from PIL import Image
sc=sys.argv[1]
d=np.asarray(Image.open(f'{sc}/disp1.png')).astype(float)
H,W=d.shape
ys,xs=np.nonzero(d>0)
rng=np.random.default_rng(1)
best=None
for it in range(400):
    idx=rng.choice(len(xs),3,replace=False)
    A=np.c_[xs[idx],ys[idx],np.ones(3)]
    try: p=np.linalg.solve(A,d[ys[idx],xs[idx]])
    except np.linalg.LinAlgError: continue
    pred=p[0]*xs+p[1]*ys+p[2]
    inl=np.abs(pred-d[ys,xs])<=2
    if best is None or inl.sum()>best[0]: best=(inl.sum(),p,inl)
n,p,inl=best
print('plane inliers share', n/len(xs), file=sys.stderr)
# choose 6 spread points among inliers: grid cells
pts=[]
xi,yi=xs[inl],ys[inl]
for (cx,cy) in [(0.2,0.25),(0.5,0.25),(0.8,0.25),(0.2,0.75),(0.5,0.75),(0.8,0.75)]:
    k=np.argmin((xi-cx*W)**2+(yi-cy*H)**2)
    pts.append((xi[k],yi[k]))
# view-1 coords with disparity per step = value/8 (half size, 4 steps); view k: x - (k-1)*v/8
lines=[]
for k in [0,2,4,6]:
    row=[]
    for (x,y) in pts:
        v=p[0]*x+p[1]*y+p[2]
        row += [x-(k-1)*v/8.0, y]
    lines.append(' '.join(f'{c:.2f}' for c in row))
print('\n'.join(lines))
