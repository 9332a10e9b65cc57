/* test_driver.c -- host test driver of ik5r.c: text vectors on stdin, results on stdout.
 *
 * Built by ik5r.firmware.csolver.build_test_driver() (with -fsanitize=undefined,address and
 * -DIK5R_CHECK_BOUNDS in the test suite). One command per line, decimal integers:
 *
 *   S px py pz ax ay az nx ny nz ox oy oz has_roll shoulder_back elbow_down q5_default_a
 *       -> q1 q2 q3 q4 q5 status                       (ik5r_solve)
 *   A y x          -> angle magnitude zero               (ik5r_atan2)
 *   R x y angle    -> x' y' flags                        (ik5r_rotate)
 *   C x            -> angle sine flags                   (ik5r_acos)
 *   Q x frac       -> root                               (ik5r_sqrt_word)
 *   I radicand bits nearest -> root                      (ik5r_isqrt64, radicand unsigned)
 *
 * Exit status: 0 after the last line; 2 on a malformed line; 3 when ik5r_self_check() fails.
 */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>

#include "ik5r.h"

#define MAX_FIELDS 17

static int parse(char *line, long long *values, int count, char **kind)
{
    char *cursor = line, *end;
    int i;

    while (*cursor == ' ')
        cursor++;
    *kind = cursor;
    while (*cursor != ' ' && *cursor != '\0' && *cursor != '\n')
        cursor++;
    for (i = 0; i < count; i++) {
        values[i] = strtoll(cursor, &end, 10);
        if (end == cursor)
            return 0;
        cursor = end;
    }
    return 1;
}

int main(void)
{
    char line[1024];
    long long v[MAX_FIELDS];
    char *kind;
    unsigned long lineno = 0;
    int check = ik5r_self_check();

    if (check != 0) {
        fprintf(stderr, "ik5r_self_check failed: %d\n", check);
        return 3;
    }
    while (fgets(line, sizeof line, stdin) != NULL) {
        lineno++;
        if (line[0] == '\n' || line[0] == '#')
            continue;
        switch (line[0]) {
        case 'S': {
            int32_t p[3], a[3], n[3], o[3], q[5];
            uint32_t status;
            int i;
            if (!parse(line, v, 16, &kind))
                goto bad;
            for (i = 0; i < 3; i++) {
                p[i] = (int32_t)v[i];
                a[i] = (int32_t)v[3 + i];
                n[i] = (int32_t)v[6 + i];
                o[i] = (int32_t)v[9 + i];
            }
            status = ik5r_solve(p, a, n, o, (int)v[12], (int)v[13], (int)v[14], (int32_t)v[15], q);
            printf("%" PRId32 " %" PRId32 " %" PRId32 " %" PRId32 " %" PRId32 " %" PRIu32 "\n",
                   q[0], q[1], q[2], q[3], q[4], status);
            break;
        }
        case 'A': {
            int32_t angle, magnitude;
            int zero;
            if (!parse(line, v, 2, &kind))
                goto bad;
            zero = ik5r_atan2((int32_t)v[0], (int32_t)v[1], &angle, &magnitude);
            printf("%" PRId32 " %" PRId32 " %d\n", angle, magnitude, zero);
            break;
        }
        case 'R': {
            int32_t xo, yo;
            uint32_t flags;
            if (!parse(line, v, 3, &kind))
                goto bad;
            flags = ik5r_rotate((int32_t)v[0], (int32_t)v[1], (int32_t)v[2], &xo, &yo);
            printf("%" PRId32 " %" PRId32 " %" PRIu32 "\n", xo, yo, flags);
            break;
        }
        case 'C': {
            int32_t angle, sine;
            uint32_t flags;
            if (!parse(line, v, 1, &kind))
                goto bad;
            flags = ik5r_acos((int32_t)v[0], &angle, &sine);
            printf("%" PRId32 " %" PRId32 " %" PRIu32 "\n", angle, sine, flags);
            break;
        }
        case 'Q': {
            if (!parse(line, v, 2, &kind))
                goto bad;
            printf("%" PRId64 "\n", ik5r_sqrt_word((int32_t)v[0], (int)v[1]));
            break;
        }
        case 'I': {
            char *cursor = line + 1, *end;
            unsigned long long radicand = strtoull(cursor, &end, 10);
            long bits, nearest;
            if (end == cursor)
                goto bad;
            cursor = end;
            bits = strtol(cursor, &end, 10);
            if (end == cursor)
                goto bad;
            cursor = end;
            nearest = strtol(cursor, &end, 10);
            if (end == cursor)
                goto bad;
            printf("%" PRIu64 "\n", ik5r_isqrt64((uint64_t)radicand, (int)bits, (int)nearest));
            break;
        }
        default:
            goto bad;
        }
    }
    return 0;
bad:
    fprintf(stderr, "line %lu: malformed: %s", lineno, line);
    return 2;
}
