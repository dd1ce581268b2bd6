"""The μ(I) and φ(I) table, fits and figure of a shear directory (scripts/shear_rheology.py).

    /usr/bin/python3 scripts/shear_figures.py out/shear [--docs]

Writes OUT/rheology.md (the reference runs, the fitted laws, the variants against their reference runs), OUT/rheology.json and OUT/rheology.png;
--docs copies them to docs/data/shear_rheology.{md,json} and docs/figures/shear_rheology.png.
"""
import argparse
import os
import shutil
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.analysis import rheology  # noqa: E402
from yadecd.io import write_json_atomic  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))
parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('directory')
parser.add_argument('--docs', action='store_true')
args = parser.parse_args()
records = rheology.load_records(args.directory)
if not records:
    sys.exit('no shear runs (*_I*_n*_s*.json) in %s' % args.directory)
fits = {m: rheology.fit_laws(records, m) for m in sorted({r['method'] for r in records})}
text = rheology.table_markdown(records) + '\n| method | μ_s | b (μ = μ_s + b I) | φ_c | a (φ = φ_c − a I) | χ²/dof μ, φ | runs |\n| --- | --- | --- | --- | --- | --- | --- |\n'
for m, f in fits.items():
    text += '| %s | %.4f ± %.4f | %.3f ± %.3f | %.4f ± %.4f | %.3f ± %.3f | %.2g, %.2g | %d |\n' % (
        m.upper(), f['mu_s'], f['mu_s_err'], f['b'], f['b_err'], f['phi_c'], f['phi_c_err'], f['a'], f['a_err'],
        f['chi2_mu'], f['chi2_phi'], f['points'])
variants = rheology.variants_markdown(records)
if variants:
    text += '\nRuns off the reference protocol (variants), against the reference run at the same nominal I:\n\n' + variants
md, js, png = (os.path.join(args.directory, 'rheology.' + e) for e in ('md', 'json', 'png'))
with open(md, 'w') as f:
    f.write(text)
write_json_atomic(js, dict(records=records, fits=fits))
rheology.figure(records, png, fits)
print(text)
if args.docs:
    shutil.copy(md, os.path.join(REPO, 'docs', 'data', 'shear_rheology.md'))
    shutil.copy(js, os.path.join(REPO, 'docs', 'data', 'shear_rheology.json'))
    shutil.copy(png, os.path.join(REPO, 'docs', 'figures', 'shear_rheology.png'))
