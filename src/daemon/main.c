/* SPDX-License-Identifier: MIT
 * gearsimd: placeholder until the service lands. */
#include <stdio.h>
int main(void) { puts("gearsimd"); return 0; }
