import sys, csv
import numpy as np
from scipy import signal
import generate as g
for seed in [int(s) for s in sys.argv[1:]]:
    meta, rec, fl, p, exc, t, x, v, a, icmd = g.base_law_rig(seed)
    meas = meta["measurement"]; fs, m, fc = exc["fs_hz"], exc["oversampling"], meas["aa_cutoff_hz"]
    sos = signal.butter(2, fc, fs=fs * m, output="sos")
    filt = lambda y: signal.sosfilt(sos, y, zi=signal.sosfilt_zi(sos) * y[0])[0][::m]
    vf, af = filt(v), filt(a)
    rows = list(csv.DictReader(open('/tmp/s58/%04d.res.csv' % seed)))
    vh = np.array([float(r['velocity_m_s']) for r in rows]); sv=np.array([float(r['velocity_sigma_m_s']) for r in rows])
    n=len(vh); vf=vf[:n]; af=af[:n]
    e=vh-vf
    # jerk
    j=np.gradient(af,1/fs)
    near = np.abs(vf) < 0.1*np.max(np.abs(vf))
    X=np.c_[np.ones(near.sum()), af[near], j[near]]
    coef,*_=np.linalg.lstsq(X,e[near],rcond=None)
    res=e[near]-X@coef
    print(seed, meas['velocity'], fs, 'fc/fs %.3f'%(fc/fs), 'near n',near.sum(),'e rms %.2e'%np.sqrt(np.mean(e[near]**2)),'fit: off %.2e, -delay %.2e s (%.3f samples), jerk coef %.2e; resid rms %.2e; stated med %.2e; z rms %.2f' % (coef[0],coef[1],coef[1]*fs,coef[2],np.sqrt(np.mean(res**2)),np.median(sv[near]), np.sqrt(np.mean((e[near]/sv[near])**2))))
