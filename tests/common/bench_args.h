/* Command lines of the bench tools: an optional positional argument (the
 * scene) and "--name value" pairs, each bound to a variable by a table. */
#ifndef GS_TESTS_BENCH_ARGS_H
#define GS_TESTS_BENCH_ARGS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *name; /* "--h" */
    char kind;        /* 'd' double, 'i' int, 's' string */
    void *to;
} bench_opt;

/* Fills the bound variables; *positional (NULL: none accepted) takes the
 * argument that is not an option. 0, or 2 (the usage exit) after saying
 * what is wrong on stderr. */
static inline int bench_args(int argc, char **argv, const char **positional, const bench_opt *opt, size_t n)
{
    for (int i = 1; i < argc; i++) {
        if (argv[i][0] != '-') {
            if (!positional) {
                fprintf(stderr, "unexpected argument %s\n", argv[i]);
                return 2;
            }
            *positional = argv[i];
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "%s: value missing\n", argv[i]);
            return 2;
        }
        const char *k = argv[i], *v = argv[++i];
        size_t j = 0;
        while (j < n && strcmp(k, opt[j].name) != 0)
            j++;
        if (j == n) {
            fprintf(stderr, "unknown option %s\n", k);
            return 2;
        }
        if (opt[j].kind == 'd')
            *(double *)opt[j].to = atof(v);
        else if (opt[j].kind == 'i')
            *(int *)opt[j].to = atoi(v);
        else
            *(const char **)opt[j].to = v;
    }
    return 0;
}

#endif
