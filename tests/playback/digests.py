#!/usr/bin/env python3
"""Digests of a work folder's outputs, to prove that a change which should not move a number
did not: every PLY, EXR and PNG byte for byte (SHA-256), every JSON once the keys that differ
from run to run by nature are taken out (timings, rates, peak memory, and the fingerprint,
which hashes paths) and the run's folders are replaced by placeholders.

Used by the playback tests (sample_playback.py, reference_scene.py) with --digests FILE:
compare against FILE, or with --record-digests write it. The digest files live in
tests/playback/digests/; a change that means to move an output records them again and says
why in its commit.
"""
import hashlib, json, os

# Keys that are not results: they change between two runs of the same build on the same input.
# faces_s, map_s, time_s: the occluders' report (irradiance.json's occluders and its planes).
VOLATILE = {'timings_s', 'wall_time_s', 'cpu_time_s', 'peak_rss_mb', 'rays_per_second', 'fingerprint', 'git_commit',
            'faces_s', 'map_s', 'time_s'}
KINDS = ('.ply', '.exr', '.png', '.json', '.glb', '.obj', '.mtl')


def _normalise(value, places):
    if isinstance(value, dict):
        return {_normalise(k, places): _normalise(v, places) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [_normalise(v, places) for v in value]
    if isinstance(value, str):
        for path, name in places:
            value = value.replace(path, name)
    return value


def digest_folder(work, places, prefix=''):
    """{prefix + file name: hex digest} for the outputs directly in work. places: (path,
    placeholder) pairs replaced in JSON strings, longest path first."""
    places = sorted(places, key=lambda p: -len(p[0]))
    out = {}
    for name in sorted(os.listdir(work)):
        path = os.path.join(work, name)
        if not os.path.isfile(path) or not name.endswith(KINDS):
            continue
        if name.endswith('.json'):
            data = json.dumps(_normalise(json.load(open(path)), places), sort_keys=True).encode()
        else:
            data = open(path, 'rb').read()
        out[prefix + name] = hashlib.sha256(data).hexdigest()
    return out


def check(digests, path, record):
    """Compares digests with the file at path (or writes it when record). Returns the list of
    problems, empty when they agree."""
    if record:
        tmp = path + '.tmp'
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(tmp, 'w') as fh:
            json.dump(digests, fh, indent=1, sort_keys=True)
            fh.write('\n')
        os.replace(tmp, path)
        print('recorded %d digests in %s' % (len(digests), path))
        return []
    want = json.load(open(path))
    problems = []
    for name in sorted(set(want) | set(digests)):
        if name not in digests:
            problems.append('%s: expected, not written' % name)
        elif name not in want:
            problems.append('%s: written, not in %s (record the digests again if it is new)' % (name, path))
        elif want[name] != digests[name]:
            problems.append('%s: differs from the recorded output' % name)
    print('digests: %d files compared with %s, %d differ' % (len(digests), path, len(problems)))
    return problems
