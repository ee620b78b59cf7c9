/* effective: the configuration in effect, every key with its value and where the value came
 * from (built-in default, the config file, or --set on the command line), as INI text that
 * reads back (--print-config) and as JSON (metrics.json's "effective_config"). */
#ifndef RS_EFFECTIVE_H
#define RS_EFFECTIVE_H

#include <stdio.h>
#include "common/config.h"
#include "common/json.h"

/* Printed at the end of every --help: the one rule users trip over. */
#define RS_PATHS_NOTE                                                                                      \
    "Relative paths in CONFIG are relative to CONFIG's folder; given with --set, to the current folder.\n" \
    "configs/KEYS.md lists every key with its default.\n"

/* The sections named in words (space-separated base names: "capture" also prints
 * [capture.NAME] sections the config has), keys in table order with a comment naming the
 * origin of each value: "samples = 256   ; default". Unset keys without default are left out. */
void rs_config_print_sections(const rs_config *cfg, const char *words, FILE *out);

/* Every section of the key table (and each [capture.NAME] the config has) into obj:
 * {"mesh": {"facet_size": {"value": "0.3", "from": "file"}, ...}, ...}; and the --set
 * overrides in effect as an array "section.key=value" under "set" of obj. */
void rs_config_effective_json(const rs_config *cfg, rs_json *obj);

#endif
