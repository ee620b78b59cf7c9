#!/usr/bin/env python3
"""The run report (pipeline/report.h) in headless Chromium (issue 23): the sample run's
report.html, then the same folder with a small albedo.glb and `rhoscan report WORKDIR`, opened
with Debian's chromium through chromium-driver (python3-selenium). Checks that the console has no
error, that every image and script loaded, that nothing but file: and data: URLs was requested,
that the expected sections are there and every camera-view image has a colour bar; saves a
screenshot of each page into the build folder (report_page.png is the README's
docs/images/report.png). Skips (77) when Chromium, its driver or selenium is missing, fails then
under CI=true.

Usage: report_page.py --bin BUILD_DIR --config CONFIG [--out DIR]
"""
import argparse, json, os, shutil, struct, subprocess, sys, tempfile

SECTIONS = ['summary', 'views', 'plots', 'counts', 'stages', 'warnings', 'config', 'provenance']
VIEWS = ['observed radiance', 'sky irradiance E_sky', 'interreflected irradiance G', 'albedo',
         're-rendered radiance', 'signed difference (re-rendered - observed)', 'albedo uncertainty',
         'panorama, filled sky marked']


def skip(why):
    if os.environ.get('CI') == 'true':
        print('FAIL (CI=true): %s' % why)
        sys.exit(1)
    print('SKIP: %s' % why)
    sys.exit(77)


def tiny_glb(path):
    """A valid glTF 2.0 binary: one triangle with a red base colour."""
    pos = struct.pack('<9f', 0, 0, 0, 1, 0, 0, 0, 0, 1)
    doc = {'asset': {'version': '2.0', 'generator': 'report_page.py'}, 'scene': 0,
           'scenes': [{'nodes': [0]}], 'nodes': [{'mesh': 0}],
           'meshes': [{'primitives': [{'attributes': {'POSITION': 0}, 'material': 0}]}],
           'materials': [{'pbrMetallicRoughness': {'baseColorFactor': [0.8, 0.1, 0.1, 1], 'metallicFactor': 0}}],
           'buffers': [{'byteLength': len(pos)}],
           'bufferViews': [{'buffer': 0, 'byteOffset': 0, 'byteLength': len(pos), 'target': 34962}],
           'accessors': [{'bufferView': 0, 'componentType': 5126, 'count': 3, 'type': 'VEC3',
                          'min': [0, 0, 0], 'max': [1, 0, 1]}]}
    js = json.dumps(doc).encode()
    js += b' ' * (-len(js) % 4)
    body = struct.pack('<II', len(js), 0x4E4F534A) + js + struct.pack('<II', len(pos), 0x004E4942) + pos
    with open(path, 'wb') as fh:
        fh.write(struct.pack('<III', 0x46546C67, 2, 12 + len(body)) + body)


def open_driver():
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        skip('python3-selenium is not installed (tools/setup-debian.sh --tests)')
    chrome, driver = shutil.which('chromium'), shutil.which('chromedriver')
    if not chrome or not driver:
        skip('chromium or chromium-driver is not installed (tools/setup-debian.sh --tests)')
    opts = webdriver.ChromeOptions()
    opts.binary_location = chrome
    profile = tempfile.mkdtemp(prefix='rhoscan-chromium-')
    for flag in ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
                 '--disable-background-networking', '--disable-component-update', '--disable-sync',
                 '--window-size=1700,2600', '--user-data-dir=' + profile]:
        opts.add_argument(flag)
    opts.set_capability('goog:loggingPrefs', {'browser': 'ALL', 'performance': 'ALL'})
    return webdriver.Chrome(service=Service(driver), options=opts), profile


REQUESTS = {}  # requestId -> (url, documentURL), over the whole session


def check_page(drv, page, shot, want_model):
    """The problems found on page (a list; empty when it passes)."""
    drv.get('about:blank')  # let the first tab's own start-up settle before the page
    for entry in drv.get_log('performance'):  # before the page: Chromium's own start-up
        msg = json.loads(entry['message'])['message']
        if msg['method'] == 'Network.requestWillBeSent':
            REQUESTS[msg['params']['requestId']] = (msg['params']['request']['url'], msg['params'].get('documentURL', ''))
    drv.get('file://' + page)
    problems = []
    if want_model:  # the viewer either shows the model or its fallback, once the scripts ran
        import time
        for _ in range(50):
            if drv.execute_script("var v=document.getElementById('model3d_view'),f=document.getElementById("
                                  "'model3d_fallback');return v.getAttribute('data-loaded')=='1'||"
                                  "f.style.display=='block';"):
                break
            time.sleep(0.1)
    for entry in drv.get_log('browser'):
        if entry['level'] == 'SEVERE':
            problems.append('console error: %s' % entry['message'])
    for entry in drv.get_log('performance'):
        msg = json.loads(entry['message'])['message']
        if msg['method'] == 'Network.requestWillBeSent':
            url, doc = msg['params']['request']['url'], msg['params'].get('documentURL', '')
            REQUESTS[msg['params']['requestId']] = (url, doc)
            # The page's own requests must stay on file: and data:; none may leave the machine
            # (Chromium's own chrome:// pages, such as the first tab's, are not the page's).
            # blob: is memory (GLTFLoader hands a .glb's embedded textures to the page that way).
            if (doc.startswith('file:') and not url.startswith(('file:', 'data:', 'blob:'))) or \
                    url.startswith(('http:', 'https:', 'ws:', 'wss:', 'ftp:')):
                problems.append('network request: %s (from %s)' % (url, doc))
        if msg['method'] == 'Network.loadingFailed':
            url, doc = REQUESTS.get(msg['params']['requestId'], ('?', '?'))
            if doc.startswith('file:') or url.startswith('file:'):  # the page's own files must all load
                problems.append('failed to load: %s (%s)' % (url, msg['params'].get('errorText')))
            else:
                print('note: Chromium itself failed to load %s from %s (%s): not the page\'s' %
                      (url, doc, msg['params'].get('errorText')))
    bad = drv.execute_script("return Array.from(document.images).filter(i=>!(i.complete&&i.naturalWidth>0))"
                             ".map(i=>i.src);")
    problems += ['image did not load: %s' % s for s in bad]
    ids = drv.execute_script("return Array.from(document.querySelectorAll('[id]')).map(e=>e.id);")
    for s in SECTIONS + (['model3d'] if want_model else []):
        if s not in ids:
            problems.append('section %s missing' % s)
    figures = drv.execute_script("return Array.from(document.querySelectorAll('figure.view')).map(f=>[f.querySelector"
                                 "('figcaption').textContent,f.querySelectorAll('svg.colorbar text').length]);")
    titles = [f[0] for f in figures]
    for v in VIEWS:
        if v not in titles:
            problems.append('camera-view image "%s" missing' % v)
    for title, ntext in figures:
        if ntext < 6:  # five numbers and the unit
            problems.append('image "%s": colour bar without numbers and unit' % title)
    if want_model:
        scripts = drv.execute_script("return [typeof THREE, typeof THREE.GLTFLoader, typeof THREE.OrbitControls];")
        if scripts != ['object', 'function', 'function']:
            problems.append('three.js scripts did not all load: %s' % scripts)
    drv.save_screenshot(shot)
    print('%s: %d images, %d problems; screenshot %s' % (page, len(figures), len(problems), shot))
    return problems


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--bin', required=True)
    ap.add_argument('--config', required=True)
    ap.add_argument('--out')
    a = ap.parse_args()
    out = a.out or a.bin
    work = os.path.join(out, 'report_page_work')
    shutil.rmtree(work, ignore_errors=True)
    rhoscan = os.path.join(a.bin, 'rhoscan')
    subprocess.run([rhoscan, 'run', a.config, '--set', 'pipeline.workdir=' + work, '--quiet'], check=True)
    page = os.path.join(work, 'report.html')
    if not os.path.exists(page):
        print('FAIL: rhoscan run wrote no report.html')
        return 1
    drv, profile = open_driver()
    try:
        problems = check_page(drv, page, os.path.join(out, 'report_page.png'), False)
        tiny_glb(os.path.join(work, 'albedo.glb'))
        subprocess.run([rhoscan, 'report', work], check=True)
        problems += check_page(drv, page, os.path.join(out, 'report_page_model.png'), True)
    finally:
        drv.quit()
        shutil.rmtree(profile, ignore_errors=True)
    for p in problems:
        print('FAIL: ' + p)
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
