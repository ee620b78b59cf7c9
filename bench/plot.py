#!/usr/bin/env python3
"""plot: SVG plots of rhoscan-bench's CSV, standard library only.

  bench/plot.py bench.csv OUTDIR
writes OUTDIR/time_vs_error.svg (CPU time of observe + irradiance + reflectance + render
against the albedo error, one colour per facet count, the Pareto front of each count joined
and ringed), OUTDIR/scaling.svg (CPU time per stage against facet count, log-log, rows named
'scale' or 'default') and OUTDIR/tables.md (every row as a markdown table).
CPU time (user + system of the stage programs) is plotted because wall time on a shared
machine measures the other jobs too; both are in the tables.
"""
import csv, math, sys

COLOURS = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#8c564b', '#17becf']
W, H, L, R, T, B = 720, 480, 80, 170, 30, 60


def axis_map(lo, hi, a, b, log):
    f = (lambda v: math.log10(v)) if log else (lambda v: v)
    lo, hi = f(lo), f(hi)
    if hi <= lo:
        hi = lo + 1
    return lambda v: a + (f(v) - lo) / (hi - lo) * (b - a)


def ticks(lo, hi, log):
    if log:
        return [10.0 ** e for e in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1)]
    step = 10 ** math.floor(math.log10((hi - lo) or 1))
    if (hi - lo) / step < 4:
        step /= 2
    return [k * step for k in range(math.floor(lo / step), math.ceil(hi / step) + 1)]


def svg_frame(title, xlabel, ylabel, xr, yr, xlog, ylog):
    X = axis_map(xr[0], xr[1], L, W - R, xlog)
    Y = axis_map(yr[0], yr[1], H - B, T, ylog)
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif" '
           'font-size="12">' % (W, H), '<rect width="100%" height="100%" fill="white"/>',
           '<text x="%d" y="18" font-size="14">%s</text>' % (L, title)]
    for t in ticks(*xr, xlog):
        if xr[0] <= t <= xr[1]:
            out.append('<line x1="%.1f" y1="%d" x2="%.1f" y2="%d" stroke="#ddd"/>' % (X(t), T, X(t), H - B))
            out.append('<text x="%.1f" y="%d" text-anchor="middle">%g</text>' % (X(t), H - B + 16, t))
    for t in ticks(*yr, ylog):
        if yr[0] <= t <= yr[1]:
            out.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#ddd"/>' % (L, Y(t), W - R, Y(t)))
            out.append('<text x="%d" y="%.1f" text-anchor="end">%g</text>' % (L - 6, Y(t) + 4, t))
    out.append('<rect x="%d" y="%d" width="%d" height="%d" fill="none" stroke="black"/>' % (L, T, W - R - L, H - B - T))
    out.append('<text x="%d" y="%d" text-anchor="middle">%s</text>' % ((L + W - R) / 2, H - 20, xlabel))
    out.append('<text transform="translate(18,%d) rotate(-90)" text-anchor="middle">%s</text>' % ((T + H - B) / 2, ylabel))
    return out, X, Y


def span(values, log, pad=0.08):
    lo, hi = min(values), max(values)
    if log:
        return lo / 1.5, hi * 1.5
    d = (hi - lo) or abs(hi) or 1
    return max(0, lo - pad * d), hi + pad * d


def pareto(points):
    """Points (time, error, label) not beaten on both time and error by another."""
    front, best = [], math.inf
    for p in sorted(points):
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def cpu_total(r):
    return r['cpu_observe'] + r['cpu_irradiance'] + r['cpu_reflectance'] + r['cpu_render']


def time_vs_error(rows, path):
    pts = [dict(r, t_total=cpu_total(r)) for r in rows if r['albedo_err'] == r['albedo_err']]
    out, X, Y = svg_frame('CPU time against albedo error (observe + irradiance + reflectance + render)',
                          'CPU time (s), log', 'albedo error (area-weighted mean relative), log',
                          span([r['t_total'] for r in pts], True), span([r['albedo_err'] for r in pts], True), True, True)
    for k, n in enumerate(sorted({r['facets'] for r in pts})):
        c = COLOURS[k % len(COLOURS)]
        mine = [(r['t_total'], r['albedo_err'], r['row']) for r in pts if r['facets'] == n]
        front = pareto(mine)
        out.append('<polyline fill="none" stroke="%s" stroke-dasharray="4 3" points="%s"/>' %
                   (c, ' '.join('%.1f,%.1f' % (X(t), Y(e)) for t, e, _ in front)))
        for t, e, name in mine:
            out.append('<circle cx="%.1f" cy="%.1f" r="3.5" fill="%s"/>' % (X(t), Y(e), c))
            out.append('<text x="%.1f" y="%.1f" font-size="9" fill="#444">%s</text>' % (X(t) + 5, Y(e) - 4, name))
        for t, e, _ in front:
            out.append('<circle cx="%.1f" cy="%.1f" r="7" fill="none" stroke="%s"/>' % (X(t), Y(e), c))
        y = T + 16 * (k + 1)
        out.append('<circle cx="%d" cy="%d" r="4" fill="%s"/><text x="%d" y="%d">%d facets</text>' %
                   (W - R + 15, y - 4, c, W - R + 25, y, n))
    y = T + 16 * (len({r['facets'] for r in pts}) + 2)
    out.append('<circle cx="%d" cy="%d" r="7" fill="none" stroke="black"/><text x="%d" y="%d">Pareto front</text>' %
               (W - R + 15, y - 4, W - R + 25, y))
    out.append('</svg>')
    open(path, 'w').write('\n'.join(out) + '\n')


def scaling(rows, path):
    pts = [dict(r, cpu_total=cpu_total(r)) for r in rows if r['row'] in ('scale', 'default')]
    stages = ['cpu_observe', 'cpu_irradiance', 'cpu_reflectance', 'cpu_render', 'cpu_total']
    vals = [r[s] for r in pts for s in stages if r[s] > 0]
    out, X, Y = svg_frame('Stage CPU time against facet count (log-log)', 'facets', 'CPU time (s)',
                          span([r['facets'] for r in pts], True), span(vals, True), True, True)
    for k, s in enumerate(stages):
        c = COLOURS[k % len(COLOURS)]
        for name, dash in (('scale', ''), ('default', '5 3')):
            mine = sorted((r['facets'], r[s]) for r in pts if r['row'] == name and r[s] > 0)
            if not mine:
                continue
            out.append('<polyline fill="none" stroke="%s" stroke-dasharray="%s" points="%s"/>' %
                       (c, dash, ' '.join('%.1f,%.1f' % (X(n), Y(t)) for n, t in mine)))
            for n, t in mine:
                out.append('<circle cx="%.1f" cy="%.1f" r="3" fill="%s"/>' % (X(n), Y(t), c))
        y = T + 16 * (k + 1)
        out.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="%s" stroke-width="2"/><text x="%d" y="%d">%s</text>' %
                   (W - R + 8, y - 4, W - R + 22, y - 4, c, W - R + 27, y, s[4:]))
    y = T + 16 * (len(stages) + 2)
    out.append('<text x="%d" y="%d" font-size="10">solid: row scale</text>' % (W - R + 8, y))
    out.append('<text x="%d" y="%d" font-size="10">dashed: row default</text>' % (W - R + 8, y + 14))
    out.append('</svg>')
    open(path, 'w').write('\n'.join(out) + '\n')


def tables(rows, path):
    head = ('| facets | row | samples / sky / sun | extra | CPU s (obs + irr + refl + render) | wall s | '
            'peak MB | rays (irradiance) | Mrays per CPU-s (irradiance) | albedo error | p90 | E error |')
    out = [head, '|' + ' --- |' * 12]
    for r in rows:
        out.append('| %d | %s | %d / %d / %d | %s | %.2f (%.2f + %.2f + %.2f + %.2f) | %.1f | %.0f | %.3g | %.2f | %.4f | %.4f | %.4f |' % (
            r['facets'], r['row'] if r['method'] == 'interreflection' else r['row'] + ' (' + r['method'] + ')',
            r['samples'], r['sky_samples'], r['sun_samples'], r['extra'], cpu_total(r), r['cpu_observe'],
            r['cpu_irradiance'], r['cpu_reflectance'], r['cpu_render'], r['t_total'], r['peak_mb'], r['rays'],
            r['rays'] / r['cpu_irradiance'] / 1e6 if r['cpu_irradiance'] > 0 else 0, r['albedo_err'],
            r['albedo_err_p90'], r['irradiance_err']))
    open(path, 'w').write('\n'.join(out) + '\n')


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    rows = []
    for r in csv.DictReader(open(sys.argv[1])):
        for k in r:
            if k not in ('row', 'method', 'extra'):
                r[k] = float(r[k]) if r[k] not in ('', 'nan', '-nan') else float('nan')
        rows.append(r)
    time_vs_error(rows, sys.argv[2] + '/time_vs_error.svg')
    scaling(rows, sys.argv[2] + '/scaling.svg')
    tables(rows, sys.argv[2] + '/tables.md')


if __name__ == '__main__':
    main()
