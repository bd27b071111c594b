/* SPDX-License-Identifier: MIT
 * The daemon's choice for `fidelity: {targets}` (gearsim/tradeoff.h) as
 * JSON on stdout, for test_fidelity_targets.py to compare with gearctl
 * advise:  tradeoff_choose TABLE SCENE OUTPUT=REL[,OUTPUT=REL...]
 * prints {"level", "h", "refine", "cost", "rejected": [labels]} or
 * {"error": field, "message": ...}. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/tradeoff.h"

int main(int argc, char **argv)
{
    if (argc != 4) {
        fprintf(stderr, "usage: tradeoff_choose TABLE SCENE OUTPUT=REL[,...]\n");
        return 2;
    }
    gs_tradeoff t;
    gs_diag d;
    if (gs_tradeoff_load(argv[1], &t, &d) != GS_OK) {
        printf("{\"error\": \"%s\"}\n", d.field);
        return 0;
    }
    int n = 0, out[GS_TRADEOFF_MAX_OUT];
    double val[GS_TRADEOFF_MAX_OUT];
    char *spec = strdup(argv[3]), *save = NULL;
    for (char *tok = strtok_r(spec, ",", &save); tok && n < GS_TRADEOFF_MAX_OUT; tok = strtok_r(NULL, ",", &save)) {
        char *eq = strchr(tok, '=');
        if (!eq)
            return 2;
        *eq = '\0';
        out[n] = gs_tradeoff_output(&t, tok);
        val[n] = atof(eq + 1);
        if (out[n] < 0) {
            printf("{\"error\": \"unknown output\"}\n");
            return 0;
        }
        n++;
    }
    gs_tradeoff_choice c;
    if (gs_tradeoff_choose(&t, argv[2], n, out, val, &c, "fidelity.targets", &d) != GS_OK) {
        printf("{\"error\": \"%s\"}\n", d.field);
    } else {
        const gs_tradeoff_row *r = &t.rows[c.row];
        char label[160];
        printf("{\"level\": \"%s\", \"h\": %.17g, \"refine\": %d, \"cost\": %.17g, \"rejected\": [", r->level, r->h,
               r->refine, r->cost);
        for (int j = 0; j < c.n_rejected; j++) {
            gs_tradeoff_label(&t.rows[c.rejected[j]], label, sizeof label);
            printf("%s\"%s\"", j ? ", " : "", label);
        }
        printf("]}\n");
    }
    gs_tradeoff_choice_clear(&c);
    gs_tradeoff_free(&t);
    free(spec);
    return 0;
}
