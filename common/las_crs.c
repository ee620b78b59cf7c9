/* las_crs: a LAS file's coordinate reference system from its GeoTIFF keys or its WKT (see
 * las_crs.h). GeoTIFF keys as the LAS 1.4 specification (R15, section 2.5) and GeoTIFF 1.0
 * (section 2.7, key codes 1024 GTModelType, 1026 GTCitation, 2048 GeographicType, 3072
 * ProjectedCSType, 3076 ProjLinearUnits, 4099 VerticalUnits) define them; WKT 1 (OGC 01-009)
 * and WKT 2 (ISO 19162) by their UNIT / LENGTHUNIT nodes. */
#include "common/las_crs.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <string.h>

/* GeoTIFF / EPSG linear unit codes rhoscan converts. */
static const struct {
    int code;
    const char *name;
    double m;
} units[] = {
    {9001, "metre", 1.0},
    {9002, "foot", 0.3048},
    {9003, "US survey foot", 1200.0 / 3937.0},
    {9005, "Clarke's foot", 0.3047972654},
    {9036, "kilometre", 1000.0},
};

static int unit_of_code(int code, const char **name, double *m)
{
    for (size_t i = 0; i < sizeof units / sizeof units[0]; i++)
        if (units[i].code == code) {
            *name = units[i].name;
            *m = units[i].m;
            return 1;
        }
    return 0;
}

static void init(rs_las_crs *crs, const char *source)
{
    memset(crs, 0, sizeof *crs);
    crs->source = source;
    crs->unit_m = crs->vunit_m = 1.0;
}

static uint16_t le16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

int rs_las_crs_geokeys(const uint8_t *dir, size_t nbytes, const char *ascii, size_t nascii, rs_las_crs *crs)
{
    init(crs, "GeoTIFF keys");
    if (nbytes < 8) return -1;
    size_t nkeys = le16(dir + 6);
    if (le16(dir) != 1 || 8 + 8 * nkeys > nbytes) return -1;
    int model = 0, vcode = 0, hcode = 0;
    for (size_t k = 0; k < nkeys; k++) {
        const uint8_t *e = dir + 8 + 8 * k;
        int id = le16(e), loc = le16(e + 2), count = le16(e + 4), value = le16(e + 6);
        if (loc == 0) {
            if (id == 1024) model = value;
            if (id == 3072 && value != 32767) crs->epsg = value;
            if (id == 2048 && value != 32767 && !crs->epsg && model != 1) crs->epsg = value;
            if (id == 3076) hcode = value;
            if (id == 4099) vcode = value;
        } else if (loc == 34737 && (id == 1026 || id == 3073 || id == 2049) && ascii &&
                   (size_t)value + (size_t)count <= nascii && (!crs->name[0] || id == 3073)) {
            size_t len = (size_t)count;
            while (len && (ascii[value + len - 1] == '|' || ascii[value + len - 1] == '\0')) len--;
            const char *bar = memchr(ascii + value, '|', len);
            if (bar) len = (size_t)(bar - (ascii + value));
            snprintf(crs->name, sizeof crs->name, "%.*s", (int)len, ascii + value);
        }
    }
    crs->kind = model == 1 ? RS_LAS_CRS_PROJECTED
        : model == 2       ? RS_LAS_CRS_GEOGRAPHIC
        : model            ? RS_LAS_CRS_OTHER
        : crs->epsg        ? RS_LAS_CRS_PROJECTED
                           : RS_LAS_CRS_NONE;
    const char *name;
    double m;
    if (hcode) {
        crs->unit_code = hcode;
        if (unit_of_code(hcode, &name, &m)) {
            snprintf(crs->unit, sizeof crs->unit, "%s", name);
            crs->unit_m = crs->vunit_m = m;
        } else {
            crs->unknown_unit = 1;
        }
    }
    if (vcode) {
        if (unit_of_code(vcode, &name, &m))
            crs->vunit_m = m;
        else if (!crs->unknown_unit) {
            crs->unknown_unit = 1;
            crs->unit_code = vcode;
        }
    }
    return 0;
}

/* WKT scanning: a node is KEYWORD[ ... ] (or with parentheses); strings are "..." with "" for a
 * quote. Positions are offsets into the text. */
typedef struct {
    const char *t;
    size_t n;
} wkt;

typedef struct {
    size_t kw, kwlen, open, close; /* the keyword, the '[' and its matching ']' */
} wnode;

static size_t skip_string(const wkt *w, size_t i)
{
    for (i++; i < w->n; i++)
        if (w->t[i] == '"') {
            if (i + 1 < w->n && w->t[i + 1] == '"')
                i++;
            else
                return i + 1;
        }
    return w->n;
}

/* The matching close of the bracket at open, or w->n. */
static size_t match(const wkt *w, size_t open)
{
    int depth = 0;
    for (size_t i = open; i < w->n;) {
        char ch = w->t[i];
        if (ch == '"') {
            i = skip_string(w, i);
            continue;
        }
        if (ch == '[' || ch == '(') depth++;
        if ((ch == ']' || ch == ')') && --depth == 0) return i;
        i++;
    }
    return w->n;
}

/* The next child node of the range [*at, end): 1 with *out, 0 when none is left. */
static int next_node(const wkt *w, size_t *at, size_t end, wnode *out)
{
    size_t i = *at;
    while (i < end) {
        char ch = w->t[i];
        if (ch == '"') {
            i = skip_string(w, i);
            continue;
        }
        if (isalpha((unsigned char)ch) || ch == '_') {
            size_t s = i;
            while (i < end && (isalnum((unsigned char)w->t[i]) || w->t[i] == '_')) i++;
            size_t e = i;
            while (i < end && isspace((unsigned char)w->t[i])) i++;
            if (i < end && (w->t[i] == '[' || w->t[i] == '(')) {
                out->kw = s, out->kwlen = e - s, out->open = i, out->close = match(w, i);
                *at = out->close < end ? out->close + 1 : end;
                return 1;
            }
            continue;
        }
        i++;
    }
    *at = end;
    return 0;
}

static int is_kw(const wkt *w, const wnode *n, const char *kw)
{
    return n->kwlen == strlen(kw) && strncmp(w->t + n->kw, kw, n->kwlen) == 0;
}

/* The node's first string argument into buf, and its first number after it (or NAN-free 0). */
static void node_args(const wkt *w, const wnode *n, char *buf, size_t size, double *num)
{
    size_t i = n->open + 1;
    if (buf) buf[0] = '\0';
    while (i < n->close && isspace((unsigned char)w->t[i])) i++;
    if (i < n->close && w->t[i] == '"') {
        size_t e = skip_string(w, i);
        size_t len = e >= i + 2 ? e - i - 2 : 0; /* without the quotes (an unterminated one: to the end) */
        if (len > 1000) len = 1000;
        if (buf) snprintf(buf, size, "%.*s", (int)len, w->t + i + 1);
        i = e;
    } else if (i < n->close && isdigit((unsigned char)w->t[i]) && num) {
        *num = strtod(w->t + i, NULL); /* ID["EPSG",26915]: handled by the caller */
    }
    while (i < n->close && (w->t[i] == ',' || isspace((unsigned char)w->t[i]))) i++;
    if (num && i < n->close) {
        if (w->t[i] == '"') i++; /* AUTHORITY["EPSG","26915"] */
        char *end;
        double v = strtod(w->t + i, &end);
        if (end != w->t + i) *num = v;
    }
}

/* A linear unit node (UNIT or LENGTHUNIT, WKT 1 and 2) into name and factor. */
static int unit_node(const wkt *w, const wnode *u, char *name, size_t size, double *m)
{
    double f = 0;
    node_args(w, u, name, size, &f);
    if (!(f > 0)) return 0;
    *m = f;
    return 1;
}

/* The horizontal system node's name, EPSG code and unit. */
static void projected(const wkt *w, const wnode *p, rs_las_crs *crs)
{
    node_args(w, p, crs->name, sizeof crs->name, NULL);
    size_t at = p->open + 1;
    wnode c;
    int have_unit = 0;
    while (next_node(w, &at, p->close, &c)) {
        double code = 0;
        if ((is_kw(w, &c, "AUTHORITY") || is_kw(w, &c, "ID"))) {
            char auth[16];
            node_args(w, &c, auth, sizeof auth, &code);
            /* EPSG codes are whole numbers below 10^6; anything else is not one (and would overflow int). */
            if (strcmp(auth, "EPSG") == 0 && code >= 1 && code < 1e6 && code == floor(code)) crs->epsg = (int)code;
        } else if (!have_unit && (is_kw(w, &c, "UNIT") || is_kw(w, &c, "LENGTHUNIT"))) {
            have_unit = unit_node(w, &c, crs->unit, sizeof crs->unit, &crs->unit_m);
        } else if (!have_unit && is_kw(w, &c, "AXIS")) { /* WKT 2: AXIS["easting (X)",east,LENGTHUNIT[...]] */
            size_t in = c.open + 1;
            wnode u;
            while (next_node(w, &in, c.close, &u))
                if (is_kw(w, &u, "LENGTHUNIT") || is_kw(w, &u, "UNIT"))
                    have_unit = unit_node(w, &u, crs->unit, sizeof crs->unit, &crs->unit_m);
        }
    }
    crs->vunit_m = crs->unit_m;
}

/* The vertical system's unit (COMPD_CS / COMPOUNDCRS). */
static void vertical(const wkt *w, const wnode *v, rs_las_crs *crs)
{
    size_t at = v->open + 1;
    wnode c;
    char name[48];
    while (next_node(w, &at, v->close, &c))
        if ((is_kw(w, &c, "UNIT") || is_kw(w, &c, "LENGTHUNIT")) && unit_node(w, &c, name, sizeof name, &crs->vunit_m))
            return;
}

static int horizontal_kind(const wkt *w, const wnode *n)
{
    if (is_kw(w, n, "PROJCS") || is_kw(w, n, "PROJCRS") || is_kw(w, n, "PROJECTEDCRS")) return RS_LAS_CRS_PROJECTED;
    if (is_kw(w, n, "GEOGCS") || is_kw(w, n, "GEOGCRS") || is_kw(w, n, "GEOGRAPHICCRS")) return RS_LAS_CRS_GEOGRAPHIC;
    if (is_kw(w, n, "GEOCCS") || is_kw(w, n, "GEODCRS") || is_kw(w, n, "GEODETICCRS")) return RS_LAS_CRS_OTHER;
    return RS_LAS_CRS_NONE;
}

int rs_las_crs_wkt(const char *text, size_t n, rs_las_crs *crs)
{
    init(crs, "WKT");
    wkt w = {text, strnlen(text, n)};
    size_t at = 0;
    wnode root;
    if (!next_node(&w, &at, w.n, &root)) return -1;
    wnode parts[4];
    int nparts = 0;
    if (is_kw(&w, &root, "COMPD_CS") || is_kw(&w, &root, "COMPOUNDCRS")) {
        size_t in = root.open + 1;
        while (nparts < 4 && next_node(&w, &in, root.close, &parts[nparts])) nparts++;
    } else {
        parts[nparts++] = root;
    }
    int found = 0;
    for (int k = 0; k < nparts; k++) {
        int kind = horizontal_kind(&w, &parts[k]);
        if (kind != RS_LAS_CRS_NONE && !found) {
            found = 1;
            crs->kind = kind;
            if (kind == RS_LAS_CRS_PROJECTED) {
                projected(&w, &parts[k], crs);
            } else {
                node_args(&w, &parts[k], crs->name, sizeof crs->name, NULL);
            }
        } else if (is_kw(&w, &parts[k], "VERT_CS") || is_kw(&w, &parts[k], "VERTCRS")) {
            vertical(&w, &parts[k], crs);
        }
    }
    if (!found) return -1;
    return 0;
}

void rs_las_crs_describe(const rs_las_crs *crs, char *buf, size_t size)
{
    if (crs->kind == RS_LAS_CRS_NONE && !crs->name[0]) {
        snprintf(buf, size, "no coordinate system given (metres assumed)");
        return;
    }
    char epsg[24] = "";
    if (crs->epsg) snprintf(epsg, sizeof epsg, " (EPSG:%d)", crs->epsg);
    snprintf(buf, size, "%s%s%s, %s%s, from the %s", crs->kind == RS_LAS_CRS_GEOGRAPHIC ? "geographic " : "",
             crs->name[0] ? crs->name : "unnamed system", epsg, crs->unit[0] ? crs->unit : "no unit given",
             crs->unit[0] || crs->unknown_unit ? "" : " (metres assumed)", crs->source);
}
