"""Odometry stress variants of a CARMEN log: the FLASER lines' odometry rewritten (ODOM lines
dropped): rotation increments scaled (ROT_SCALE), the laser late by LAG s (each scan gets the
odometry LAG s after its stamp), a heading bias per metre (CURV), and slips (KICK: at each record
with probability 1/60 a heading jump uniform in +-KICK rad and +-0.2 m in x and y, kept after).
Usage: python odometry_stress.py LOG OUT ROT_SCALE LAG [CURV [KICK]]"""
import bz2, gzip, math, sys
import numpy as np

def opener(p):
    return bz2.open(p, 'rt') if p.endswith('.bz2') else gzip.open(p, 'rt') if p.endswith('.gz') else open(p)

def main(src, dst, rot_scale=1.0, lag=0.0, curv=0.0, kick=0.0):
    rng = np.random.default_rng(7)
    lines = [l for l in opener(src) if l.startswith('FLASER')]
    recs = []
    for l in lines:
        f = l.split(); n = int(f[1])
        odo = [float(v) for v in f[2+n+3:2+n+6]]
        t = float(f[2+n+6])
        recs.append((f, n, odo, t))
    odo = np.array([r[2] for r in recs]); ts = np.array([r[3] for r in recs])
    # new odometry: compose scaled increments
    new = [odo[0].copy()]
    for i in range(1, len(odo)):
        a, b = odo[i-1], odo[i]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0]-a[0], b[1]-a[1]
        lx, ly = c*dx + s*dy, -s*dx + c*dy
        dth = math.atan2(math.sin(b[2]-a[2]), math.cos(b[2]-a[2]))
        dth = dth*rot_scale + curv*math.hypot(lx, ly)
        if kick and rng.random() < 1/60:
            dth += rng.uniform(-kick, kick); lx += rng.uniform(-0.2, 0.2); ly += rng.uniform(-0.2, 0.2)
        p = new[-1]
        c, s = math.cos(p[2]), math.sin(p[2])
        new.append(np.array([p[0] + c*lx - s*ly, p[1] + s*lx + c*ly, p[2] + dth]))
    new = np.array(new)
    if lag:
        # the laser's stamp is late: the scan stamped t was taken at t - lag; odometry at the stamp
        # runs ahead. Give each scan the odometry at t + lag (interpolated in file order index).
        order = np.arange(len(ts))
        tt = np.maximum.accumulate(ts)
        idx = np.interp(tt + lag, tt, order)
        i0 = np.floor(idx).astype(int); i1 = np.minimum(i0+1, len(ts)-1); w = idx - i0
        th = np.unwrap(new[:, 2])
        new = np.stack([new[i0,0]*(1-w)+new[i1,0]*w, new[i0,1]*(1-w)+new[i1,1]*w, th[i0]*(1-w)+th[i1]*w], 1)
    with open(dst, 'w') as out:
        for (f, n, _, _), p in zip(recs, new):
            th = math.atan2(math.sin(p[2]), math.cos(p[2]))
            vals = [f'{p[0]:.6f}', f'{p[1]:.6f}', f'{th:.6f}']
            f = f[:2+n] + vals + vals + f[2+n+6:]
            out.write(' '.join(f) + '\n')

if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]) if len(sys.argv) > 5 else 0.0, float(sys.argv[6]) if len(sys.argv) > 6 else 0.0)
