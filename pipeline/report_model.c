/* report_model: the report's interactive 3D view of the textured export (albedo.glb, when the
 * work folder has it): three.js r111 from Debian's libjs-three (three.min.js, its examples'
 * GLTFLoader.js and OrbitControls.js, classic scripts that run from file://) copied into
 * WORKDIR/report/three/, the model embedded as base64 (a double-clicked file:// page cannot
 * fetch a .glb), and the albedo image as the fallback when WebGL or the scripts are missing. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"
#include "pipeline/report.h"
#include "pipeline/report_priv.h"

#define THREE_DEFAULT "/usr/share/javascript/three"

static const char *const THREE_FILES[][2] = {{"three.min.js", "three.min.js"},
                                             {"examples/js/loaders/GLTFLoader.js", "GLTFLoader.js"},
                                             {"examples/js/controls/OrbitControls.js", "OrbitControls.js"}};

/* Copies the scripts into workdir/report/three/: 0, or -1 when one is missing or unwritable. */
static int copy_three(const char *three, const char *workdir)
{
    char dir[4096], from[4096], to[4096];
    snprintf(dir, sizeof dir, "%s/report/three", workdir);
    if (rs_mkdir_p(dir, NULL) != 0) return -1;
    for (size_t k = 0; k < sizeof THREE_FILES / sizeof *THREE_FILES; k++) {
        char *data = NULL;
        size_t size;
        rs_path_join(from, sizeof from, three, THREE_FILES[k][0]);
        rs_path_join(to, sizeof to, dir, THREE_FILES[k][1]);
        if (rs_read_file(from, &data, &size, NULL) != 0) return -1;
        int rc = 0;
        char *old = NULL;
        size_t old_size;
        if (rs_read_file(to, &old, &old_size, NULL) != 0 || old_size != size || memcmp(old, data, size) != 0)
            rc = rs_write_file_atomic(to, data, size, NULL);
        free(old);
        free(data);
        if (rc != 0) return -1;
    }
    return 0;
}

static const char VIEWER_JS[] =
    "<script>(function(){var box=document.getElementById('model3d_view'),fb=document.getElementById('model3d_"
    "fallback');function fallback(why){fb.style.display='block';document.getElementById('model3d_why')."
    "textContent=why;}var c=document.createElement('canvas');var gl=null;try{gl=c.getContext('webgl')||c."
    "getContext('experimental-webgl');}catch(e){}if(!gl||!window.THREE||!THREE.GLTFLoader){fallback(gl?'three.js "
    "did not load':'this browser gives no WebGL');return;}var b64=document.getElementById('model3d_glb').textContent."
    "trim();var bin=atob(b64.slice(b64.indexOf(',')+1)),buf=new Uint8Array(bin.length);for(var i=0;i<bin.length;i++)"
    "buf[i]=bin.charCodeAt(i);var W=760,H=480,r=new THREE.WebGLRenderer({canvas:c,antialias:true});r.setSize(W,H);"
    "box.appendChild(c);var scene=new THREE.Scene();scene.background=new THREE.Color(0xdddddd);scene.add(new "
    "THREE.AmbientLight(0xffffff,1));var cam=new THREE.PerspectiveCamera(45,W/H,0.01,1e5);var ctl=new "
    "THREE.OrbitControls(cam,c);new THREE.GLTFLoader().parse(buf.buffer,'',function(g){scene.add(g.scene);var "
    "bb=new THREE.Box3().setFromObject(g.scene),ctr=bb.getCenter(new THREE.Vector3()),s=bb.getSize(new "
    "THREE.Vector3()).length()||1;cam.position.copy(ctr).add(new THREE.Vector3(0.6*s,-0.9*s,0.5*s));cam.up.set(0,0,"
    "1);ctl.target.copy(ctr);ctl.update();box.setAttribute('data-loaded','1');},function(e){fallback('the model did "
    "not load: '+e);});(function loop(){requestAnimationFrame(loop);r.render(scene,cam);})();})();</script>";

void rs_report_model3d(rs_html *h, const rs_report_opts *o)
{
    char path[4096], *glb = NULL;
    size_t size;
    if (rs_read_file(rs_path_join(path, sizeof path, o->workdir, "albedo.glb"), &glb, &size, NULL) != 0) return;
    int scripts = copy_three(o->three_dir ? o->three_dir : THREE_DEFAULT, o->workdir) == 0;
    rs_html_put(h,
                "<section id=\"model3d\"><h2>3D view of albedo.glb</h2><p class=\"note\">Drag to turn, wheel "
                "to zoom (three.js r111, copied into report/three/; the model is embedded in this page).</p>"
                "<div id=\"model3d_view\"></div><div id=\"model3d_fallback\" style=\"display:none\"><p "
                "class=\"note\">No 3D view: <span id=\"model3d_why\"></span>. The albedo in the camera's view "
                "instead:</p><img src=\"report/albedo.png\" alt=\"albedo (fallback)\" width=\"400\"></div>");
    if (scripts)
        rs_html_put(h,
                    "<script src=\"report/three/three.min.js\"></script><script "
                    "src=\"report/three/GLTFLoader.js\"></script><script "
                    "src=\"report/three/OrbitControls.js\"></script>");
    rs_html_put(h, "<script type=\"text/plain\" id=\"model3d_glb\">data:model/gltf-binary;base64,");
    rs_html_base64(h, (const unsigned char *)glb, size);
    rs_html_put(h, "</script>");
    rs_html_put(h, VIEWER_JS);
    rs_html_put(h, "</section>");
    free(glb);
}
