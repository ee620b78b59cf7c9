/* e57_file: the E57 file's physical layer (ASTM E2807, section 6): 1024-byte pages whose last
 * 4 bytes are the CRC-32C (Castagnoli) of the other 1020, stored big-endian; logical offsets
 * count only the pages' data bytes. Pages are read E57_CACHE_PAGE at a time and checked once. */
#include "common/e57_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <nmmintrin.h>
#define E57_CRC_HW 1
#endif

static uint32_t crc_table[8][256];

static void crc_init(void)
{
    for (uint32_t i = 0; i < 256; i++) {
        uint32_t c = i;
        for (int k = 0; k < 8; k++) c = c & 1 ? (c >> 1) ^ 0x82f63b78u : c >> 1;
        crc_table[0][i] = c;
    }
    for (uint32_t i = 0; i < 256; i++)
        for (int t = 1; t < 8; t++)
            crc_table[t][i] = (crc_table[t - 1][i] >> 8) ^ crc_table[0][crc_table[t - 1][i] & 0xff];
}

/* Slicing by 8: 8 bytes per step through 8 tables. */
static uint32_t crc_soft(const uint8_t *p, size_t n)
{
    uint32_t c = 0xffffffffu;
    while (n >= 8) {
        uint32_t lo = c ^ ((uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24);
        c = crc_table[7][lo & 0xff] ^ crc_table[6][(lo >> 8) & 0xff] ^ crc_table[5][(lo >> 16) & 0xff] ^
            crc_table[4][lo >> 24] ^ crc_table[3][p[4]] ^ crc_table[2][p[5]] ^ crc_table[1][p[6]] ^ crc_table[0][p[7]];
        p += 8;
        n -= 8;
    }
    while (n--) c = (c >> 8) ^ crc_table[0][(c ^ *p++) & 0xff];
    return ~c;
}

#ifdef E57_CRC_HW
__attribute__((target("sse4.2"))) static uint32_t crc_hw(const uint8_t *p, size_t n)
{
    uint64_t c = 0xffffffffu;
    while (n >= 8) {
        uint64_t v;
        memcpy(&v, p, 8);
        c = _mm_crc32_u64(c, v);
        p += 8;
        n -= 8;
    }
    uint32_t c32 = (uint32_t)c;
    while (n--) c32 = _mm_crc32_u8(c32, *p++);
    return ~c32;
}
#endif

uint32_t rs_e57_crc32c(const void *data, size_t n)
{
    static int mode; /* 0: not chosen yet, 1: software, 2: SSE 4.2 */
    if (!mode) {
        crc_init();
        mode = 1;
#ifdef E57_CRC_HW
        __builtin_cpu_init();
        if (__builtin_cpu_supports("sse4.2")) mode = 2;
#endif
    }
#ifdef E57_CRC_HW
    if (mode == 2) return crc_hw(data, n);
#endif
    return crc_soft(data, n);
}

static uint64_t le64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | p[i];
    return v;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Bytes at a physical offset (no checking). */
static int read_physical(e57_file *f, uint64_t off, void *buf, size_t n, rs_err *err)
{
    if (off > f->size || n > f->size - off)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "offset %llu: %zu bytes wanted past the end of the file (%llu bytes); it is truncated",
                          (unsigned long long)off, n, (unsigned long long)f->size);
    if (f->mem) {
        memcpy(buf, f->mem + off, n);
        return 0;
    }
    size_t got = 0;
    while (got < n) {
        ssize_t r = pread(f->fd, (char *)buf + got, n - got, (off_t)(off + got));
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) return rs_err_errno(err, f->name, "reading %zu bytes at offset %llu", n, (unsigned long long)off);
        if (r == 0)
            return rs_err_set(err, RS_ERR_INPUT, f->name, 0, "offset %llu: the file ends early (truncated while read)",
                              (unsigned long long)(off + got));
        got += (size_t)r;
    }
    return 0;
}

/* Loads the block of pages holding page into the cache and checks their CRCs. */
static int load_pages(e57_file *f, uint64_t page, rs_err *err)
{
    uint64_t first = page - page % E57_CACHE_PAGE;
    uint64_t n = f->npages - first < E57_CACHE_PAGE ? f->npages - first : E57_CACHE_PAGE;
    f->cache_n = 0;
    if (read_physical(f, first * E57_PAGE, f->cache, (size_t)(n * E57_PAGE), err) != 0) return -1;
    for (uint64_t k = 0; k < n; k++) {
        const uint8_t *p = f->cache + k * E57_PAGE;
        uint32_t want = (uint32_t)p[1020] << 24 | (uint32_t)p[1021] << 16 | (uint32_t)p[1022] << 8 | p[1023];
        uint32_t got = rs_e57_crc32c(p, E57_PAGE_DATA);
        if (got != want)
            return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                              "offset %llu: page %llu fails its checksum (CRC-32C 0x%08x stored, 0x%08x computed); "
                              "the file is damaged",
                              (unsigned long long)((first + k) * E57_PAGE), (unsigned long long)(first + k), want, got);
    }
    f->cache_first = first;
    f->cache_n = n;
    return 0;
}

int e57_read_logical(e57_file *f, uint64_t logical, void *buf, size_t n, rs_err *err)
{
    if (logical > e57_logical_size(f) || n > e57_logical_size(f) - logical)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "logical offset %llu: %zu bytes wanted past the end of the file's %llu data bytes; the "
                          "file is truncated or the XML gives a wrong offset or length",
                          (unsigned long long)logical, n, (unsigned long long)e57_logical_size(f));
    uint8_t *out = buf;
    while (n > 0) {
        uint64_t page = logical / E57_PAGE_DATA, in = logical % E57_PAGE_DATA;
        if (!f->cache_n || page < f->cache_first || page >= f->cache_first + f->cache_n)
            if (load_pages(f, page, err) != 0) return -1;
        size_t take = E57_PAGE_DATA - in < n ? (size_t)(E57_PAGE_DATA - in) : n;
        memcpy(out, f->cache + (page - f->cache_first) * E57_PAGE + in, take);
        out += take;
        logical += take;
        n -= take;
    }
    return 0;
}

int e57_logical_of(const e57_file *f, uint64_t physical, const char *what, uint64_t *logical, rs_err *err)
{
    if (physical >= f->size || physical % E57_PAGE >= E57_PAGE_DATA)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "%s: physical offset %llu is %s; expected an offset inside a page's data (file of %llu "
                          "bytes)",
                          what, (unsigned long long)physical, physical >= f->size ? "past the end" : "inside a CRC",
                          (unsigned long long)f->size);
    *logical = physical / E57_PAGE * E57_PAGE_DATA + physical % E57_PAGE;
    return 0;
}

/* The 48-byte header: signature, version 1.x, length, the XML's place, page size 1024. */
static int check_header(e57_file *f, const uint8_t *h, rs_err *err)
{
    if (memcmp(h, "ASTM-E57", 8) != 0)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0, "offset 0: no \"ASTM-E57\" signature; expected an E57 file");
    uint32_t major = le32(h + 8);
    uint64_t length = le64(h + 16), page = le64(h + 40);
    if (major != 1)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0, "offset 8: E57 version %u.%u; expected 1.x", major,
                          le32(h + 12));
    if (page != E57_PAGE)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0, "offset 40: page size %llu; expected 1024",
                          (unsigned long long)page);
    if (length != f->size)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "offset 16: filePhysicalLength is %llu but the file has %llu bytes; it is truncated or "
                          "damaged",
                          (unsigned long long)length, (unsigned long long)f->size);
    if (f->size % E57_PAGE != 0)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0, "the file's %llu bytes are not whole 1024-byte pages",
                          (unsigned long long)f->size);
    return 0;
}

int e57_file_open(e57_file *f, const char *path, const void *mem, size_t size, rs_err *err)
{
    memset(f, 0, sizeof *f);
    f->name = path;
    f->fd = -1;
    if (mem) {
        f->mem = mem;
        f->size = size;
    } else {
        f->fd = open(path, O_RDONLY);
        struct stat st;
        if (f->fd < 0 || fstat(f->fd, &st) != 0) return rs_err_errno(err, path, "cannot open the E57 file");
        if (!S_ISREG(st.st_mode)) return rs_err_set(err, RS_ERR_INPUT, path, 0, "not a regular file");
        f->size = (uint64_t)st.st_size;
    }
    uint8_t h[48];
    if (f->size < E57_PAGE)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "%llu bytes; an E57 file has at least one 1024-byte page",
                          (unsigned long long)f->size);
    if (read_physical(f, 0, h, sizeof h, err) != 0 || check_header(f, h, err) != 0) return -1;
    f->npages = f->size / E57_PAGE;
    f->cache = malloc(E57_CACHE_PAGE * E57_PAGE);
    if (!f->cache) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    return 0;
}

void e57_file_close(e57_file *f)
{
    if (f->fd >= 0) close(f->fd);
    free(f->cache);
    f->fd = -1;
    f->cache = NULL;
}
