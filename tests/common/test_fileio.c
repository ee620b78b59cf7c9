/* Tests of the file hash used for rerun decisions: equal contents hash equal, and a change of
 * any one bit (high or low bit of a word, in the word lanes or the tail) changes the hash. */
#include <stdio.h>
#include <stdlib.h>
#include "common/fileio.h"
#include "tests/testutil.h"

static uint64_t hash_of(const char *path, const unsigned char *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    fclose(f);
    uint64_t h = 0;
    assert_int_equal(rs_hash_file(path, &h, NULL), 0);
    return h;
}

static void test_hash_file_changes(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("hash");
    const char *a = rs_test_path(dir, "a.bin"), *b = rs_test_path(dir, "b.bin");
    size_t sizes[] = {0, 1, 31, 32, 65536 + 77, 200000};
    for (size_t s = 0; s < sizeof sizes / sizeof *sizes; s++) {
        size_t n = sizes[s];
        unsigned char *d = malloc(n + 1);
        assert_non_null(d);
        for (size_t k = 0; k < n; k++) d[k] = (unsigned char)(k * 131 + 7);
        uint64_t h = hash_of(a, d, n);
        assert_true(hash_of(b, d, n) == h);
        d[n] = 0;
        assert_true(hash_of(b, d, n + 1) != h); /* one more byte */
        size_t pos[] = {0, 7, n / 2, n > 0 ? n - 1 : 0};
        for (size_t p = 0; p < 4; p++) {
            if (pos[p] >= n) continue; /* short files: position 7 lies past the end */
            for (int bit = 0; bit < 8; bit += 7) {
                d[pos[p]] ^= (unsigned char)(1u << bit);
                assert_true(hash_of(b, d, n) != h);
                d[pos[p]] ^= (unsigned char)(1u << bit);
            }
        }
        free(d);
    }
    uint64_t h;
    assert_int_equal(rs_hash_file(rs_test_path(dir, "missing"), &h, NULL), -1);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_hash_file_changes))
