"""Picks the landmarks of the CT-derived chain 455 once (docs/anatomy.md, "Real chains for the
cross-anatomy tests"): SOFA's landmarks (tests/atlas_cli/sofa-ossicles.landmarks.json) carried
by a similarity ICP of SOFA's chain surface onto the CT chain (both sides tried, best of 60
random starts), then the umbo moved onto the CT chain's own manubrium tip, and the ISJ put at
the centre of the chain's bone inside the atlas's ISJ interface carried onto the chain (the
chain fuses incus and stapes, so the interface itself is not in it). A development tool, not part
of any test run: its rounded output is the constant in tests/registration_real_anatomy.rs.

Usage: python3 tests/python/pick_ct_chain_landmarks.py ATLAS_EXPORT [SHARED_DIR]
  ATLAS_EXPORT: the folder of `otoatlas atlas export ATLAS_EXPORT` (the default atlas's surfaces);
  SHARED_DIR: default ../shared.
Needs numpy, scipy, trimesh, meshio (scripts/requirements-test.txt).
"""
import numpy as np, trimesh, meshio, json, sys, os, tomllib
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation as R
root=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
atlas_export=sys.argv[1]
sh=os.path.join(sys.argv[2] if len(sys.argv)>2 else os.path.join(root,'..','shared'),'anatomy')+'/'
m=meshio.read(sh+'sofa-ossicles/Ossicles.vtu')
pts=m.points.astype(float); tets=m.cells_dict['tetra']
faces={}
for t in tets:
    for f in ([t[0],t[1],t[2]],[t[0],t[1],t[3]],[t[1],t[2],t[3]],[t[0],t[2],t[3]]):
        k=tuple(sorted(f)); faces[k]=faces.get(k,0)+1
bf=np.array([k for k,c in faces.items() if c==1])
sofa=trimesh.Trimesh(pts,bf,process=True)
sl=json.load(open(os.path.join(root,'tests/atlas_cli/sofa-ossicles.landmarks.json')))
L=np.array([sl['umbo'],sl['incudomalleolar'],sl['incudostapedial']])
ct=trimesh.load(sh+'vision6d-ossicles/obj_mm/455_right_ossicles_processed.obj',process=False)
ctp=trimesh.sample.sample_surface(ct,8000,seed=1)[0]
tree=cKDTree(ctp)
def umeyama(X,Y,scale=True):
    mx,my=X.mean(0),Y.mean(0); Xc,Yc=X-mx,Y-my
    H=Yc.T@Xc/len(X); U,S,Vt=np.linalg.svd(H); d=np.sign(np.linalg.det(U@Vt))
    D=np.diag([1,1,d]); Rm=U@D@Vt
    s=(S*np.diag(D)).sum()/ (Xc**2).sum()*len(X) if scale else 1.0
    return s,Rm,my-s*Rm@mx
def icp(src,s,Rm,t,it=60):
    for _ in range(it):
        Y=(s*(Rm@src.T)).T+t
        d,i=tree.query(Y)
        keep=d<np.percentile(d,90)
        s,Rm,t=umeyama(src[keep],ctp[i[keep]])
    Y=(s*(Rm@src.T)).T+t; d,_=tree.query(Y)
    # symmetric
    t2=cKDTree(Y); d2,_=t2.query(ctp)
    return s,Rm,t,0.5*(d.mean()+d2.mean())
def fit(src, mark_points, mark_normals=()):
    """Similarity ICP of the surface samples `src` onto the CT chain, unmirrored and mirrored
    (x -> -x), each the best of 60 random starts then 80 iterations; returns the better side's
    scale and the carried points and normals."""
    res=[]
    for mirror in (False,True):
        sp=src.copy(); P=np.array(mark_points,float); N=np.array(mark_normals,float).reshape(-1,3)
        if mirror: sp[:,0]*=-1; P[:,0]*=-1; N[:,0]*=-1
        c=sp.mean(0)
        best=None
        for r in R.random(60,random_state=3):
            Rm=r.as_matrix(); s=1.0; t=ctp.mean(0)-Rm@c
            s,Rm,t,e=icp(sp,s,Rm,t,it=10)
            if best is None or e<best[3]: best=(s,Rm,t,e)
        s,Rm,t,e=icp(sp,*best[:3],it=80)
        print('mirror',mirror,'scale',s,'masd',e)
        res.append((e,s,(s*(Rm@P.T)).T+t,(Rm@N.T).T))
    e,s,P,N=min(res,key=lambda r:r[0])
    return s,P,N

sp=trimesh.sample.sample_surface(sofa,3000,seed=2)[0]
_,T,_=fit(sp,L)
print('transferred',T)
# umbo: ct vertex farthest from IMJ among those within 1.0 mm of transferred umbo
V=np.asarray(ct.vertices)
near=V[np.linalg.norm(V-T[0],axis=1)<1.0]
umbo=near[np.argmax(np.linalg.norm(near-T[1],axis=1))]
print('umbo snapped',umbo, 'moved',np.linalg.norm(umbo-T[0]))

# ISJ: the default atlas's ISJ interface (centre, normal, semi-axis; assets/anatomy.toml) carried
# onto the chain by a similarity ICP of the atlas's ossicle surfaces; the landmark is the centroid
# of the chain's bone inside the carried interface disc (the disc's points at 0.01 mm with a
# positive signed distance to the chain).
joint=tomllib.load(open(os.path.join(root,'assets/anatomy.toml'),'rb'))['joints']['incudostapedial']
bones=trimesh.util.concatenate([trimesh.load(os.path.join(atlas_export,'surfaces',b+'.ply'),process=False)
                                for b in ('malleus','incus','stapes')])
ap=trimesh.sample.sample_surface(bones,3000,seed=2)[0]
scale,(c,),(n,)=fit(ap,[joint['center']],[joint['normal']])
radius=min(joint['semi_axes'])*scale
n=n/np.linalg.norm(n); u=np.cross(n,[1,0,0]); u/=np.linalg.norm(u); v=np.cross(n,u)
g=np.arange(-radius,radius+0.005,0.01); X,Y=np.meshgrid(g,g); disc=X**2+Y**2<=radius**2
D=c+X[disc][:,None]*u+Y[disc][:,None]*v
depth=trimesh.proximity.ProximityQuery(ct)
bone=depth.signed_distance(D)>0
isj=D[bone].mean(0)
print('ISJ carried',c,'depth',depth.signed_distance([c])[0],'disc radius',radius,'bone fraction',bone.mean())
print('ISJ picked',isj,'depth',depth.signed_distance([isj])[0],'moved',np.linalg.norm(isj-c),
      'from the SOFA-carried ISJ',np.linalg.norm(isj-T[2]))

out=np.array([umbo,T[1],isj])
d=lambda a,b: np.linalg.norm(out[a]-out[b])
print('dist umbo-IMJ %.2f umbo-ISJ %.2f IMJ-ISJ %.2f'%(d(0,1),d(0,2),d(1,2)))
print('inside', ct.contains(out))
print(json.dumps({'umbo':list(np.round(out[0],3)),'incudomalleolar':list(np.round(out[1],3)),'incudostapedial':list(np.round(out[2],3))}))
