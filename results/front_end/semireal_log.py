"""A semi-real CARMEN log from a GMapping-corrected one: its real scans at the corrected poses (the
ground truth, written as TUM), with an odometry of our own that drifts: per step 1 % scale error,
0.001 rad/m heading bias, 1 % translation noise, 0.002 rad/m and 2 % of the turn heading noise.
Stamps are 0.2 s apart. Usage: python semireal_log.py CORRECTED.log.gz OUT_PREFIX [SEED]"""
import gzip, math, sys
import numpy as np

def main(src, dst, seed=0, scale=1.01, bias=0.001, sig_t=0.01, sig_r=0.002):
    rng = np.random.default_rng(seed)
    recs = []
    for l in gzip.open(src, 'rt'):
        if not l.startswith('FLASER'): continue
        f = l.split(); n = int(f[1])
        pose = [float(v) for v in f[2+n:2+n+3]]
        recs.append((f, n, pose))
    truth = np.array([r[2] for r in recs])
    odo = [truth[0].copy()]
    for i in range(1, len(truth)):
        a, b = truth[i-1], truth[i]
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0]-a[0], b[1]-a[1]
        lx, ly = c*dx + s*dy, -s*dx + c*dy
        dth = math.atan2(math.sin(b[2]-a[2]), math.cos(b[2]-a[2]))
        d = math.hypot(lx, ly)
        lx = lx*scale + rng.normal(0, sig_t*d + 1e-4); ly = ly*scale + rng.normal(0, sig_t*d + 1e-4)
        dth = dth + bias*d + rng.normal(0, sig_r*d + 0.02*abs(dth) + 1e-4)
        p = odo[-1]; c, s = math.cos(p[2]), math.sin(p[2])
        odo.append(np.array([p[0] + c*lx - s*ly, p[1] + s*lx + c*ly, p[2] + dth]))
    with open(dst + '.clf', 'w') as out, open(dst + '.truth.tum', 'w') as tt:
        for i, ((f, n, _), p, t) in enumerate(zip(recs, odo, truth)):
            stamp = 1000.0 + 0.2*i
            th = math.atan2(math.sin(p[2]), math.cos(p[2]))
            vals = [f'{p[0]:.6f}', f'{p[1]:.6f}', f'{th:.6f}']
            out.write(' '.join(['FLASER', str(n)] + f[2:2+n] + vals + vals + [f'{stamp:.3f}', 'semi', f'{stamp:.3f}']) + '\n')
            tt.write(f'{stamp:.3f} {t[0]:.6f} {t[1]:.6f} 0 0 0 {math.sin(t[2]/2):.9f} {math.cos(t[2]/2):.9f}\n')
            if i == 0: pass
    # odometry-only error at the end and as ATE-ish
    o = np.array(odo); print(dst, 'scans', len(o), 'odometry end error', float(np.hypot(*(o[-1,:2]-truth[-1,:2]))), 'path', float(np.sum(np.hypot(*np.diff(truth[:,:2],axis=0).T))))

if __name__ == '__main__':
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 0)
