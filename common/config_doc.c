/* config_doc: renders the key table (config_keys.c) as configs/KEYS.md, so that the reference
 * cannot drift from what the loader accepts (test_config compares the committed file). */
#include "common/config.h"
#include "common/config_priv.h"

#include <stdlib.h>
#include <string.h>

static const char header[] =
    "# rhoscan configuration keys\n"
    "\n"
    "Generated from the key table in `common/config_keys.c` by `rs_config_keys_markdown()`; do not\n"
    "edit by hand. The unit test `test_config` fails when this file and the table differ (run it\n"
    "with `RHOSCAN_UPDATE_KEYS_MD=1` set to rewrite this file).\n"
    "\n"
    "A config is an INI file: `[section]` headings, `key = value` lines, comments starting with `;`\n"
    "or `#` (after a value too, following a space). Every key is checked when the config is loaded;\n"
    "an unknown section or key, a value of the wrong form or out of range, and a key given twice\n"
    "are errors naming the file and line.\n"
    "\n"
    "- **Precedence**: built-in default < config file < `--set section.key=value` on the command\n"
    "  line. `--set` may repeat; `--set capture.north.position=\"1 2 3\"` sets a key of\n"
    "  `[capture.north]`.\n"
    "- **Relative paths** (types path and paths) in the file are relative to the folder holding the\n"
    "  config file, not to the current folder; given with `--set` on the command line, they are\n"
    "  relative to the current folder. The paths of a list are separated by spaces.\n"
    "- **Several captures**: sections `[capture]`, `[capture.NAME]`, ... each take the keys of\n"
    "  `[capture]`.\n"
    "- **Defaults**: *none* means the key is unset unless given; its help says what happens then.\n"
    "- Keys ending in `_deg` are in degrees. Booleans are true/false, yes/no, on/off or 1/0.\n";

/* A table cell: '|' escaped, line breaks flattened. */
static void put_cell(rs_cfg_buf *b, const char *s, int code)
{
    rs_cfg_buf_put(b, " ", 1);
    if (code) rs_cfg_buf_put(b, "`", 1);
    for (; *s; s++) {
        if (*s == '|')
            rs_cfg_buf_put(b, "\\|", 2);
        else if (*s == '\n' || *s == '\r')
            rs_cfg_buf_put(b, " ", 1);
        else
            rs_cfg_buf_put(b, s, 1);
    }
    if (code) rs_cfg_buf_put(b, "`", 1);
    rs_cfg_buf_put(b, " |", 2);
}

char *rs_config_keys_markdown(void)
{
    rs_cfg_buf b = {0};
    rs_cfg_buf_printf(&b, "%s", header);
    const char *section = NULL;
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        if (!section || strcmp(section, k->section) != 0) {
            section = k->section;
            rs_cfg_buf_printf(&b, "\n## [%s]\n\n", section);
            rs_cfg_buf_printf(&b, "| key | type | unit | default | stages | help |\n");
            rs_cfg_buf_printf(&b, "| --- | --- | --- | --- | --- | --- |\n");
        }
        char type[512];
        rs_cfg_describe(k, type, sizeof type);
        /* The descriptions come from error messages ("a real in ..."): drop the article. */
        const char *t = strncmp(type, "a ", 2) == 0 ? type + 2 : strncmp(type, "an ", 3) == 0 ? type + 3 : type;
        rs_cfg_buf_put(&b, "|", 1);
        put_cell(&b, k->key, 1);
        put_cell(&b, t, 0);
        put_cell(&b, k->unit ? k->unit : "", 0);
        put_cell(&b, k->def ? k->def : "*none*", k->def != NULL);
        put_cell(&b, k->stages ? k->stages : "", 0);
        put_cell(&b, k->help ? k->help : "", 0);
        rs_cfg_buf_put(&b, "\n", 1);
    }
    if (b.failed) {
        free(b.s);
        return NULL;
    }
    return b.s;
}
