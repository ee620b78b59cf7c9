/* fuzz_config: libFuzzer harness for INI configs (rs_config_load_string): libinih, the key
 * table checks, and the section text used for fingerprints. Run by tools/fuzz.sh. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/config.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = '\0';
    rs_err err;
    rs_config *cfg = rs_config_load_string(text, "fuzz.ini", "/tmp", NULL, &err);
    if (cfg) {
        /* Render every section of the key table: the formatting behind it reads every stored
         * value, defaults included. */
        for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++)
            if (k == rs_cfg_keys || strcmp(k->section, k[-1].section) != 0)
                free(rs_config_section_text(cfg, k->section));
        const char *names[16];
        int n = rs_config_sections(cfg, "capture", names, 16);
        for (int i = 0; i < n && i < 16; i++) free(rs_config_section_text(cfg, names[i]));
    }
    rs_config_free(cfg);
    free(text);
    return 0;
}
