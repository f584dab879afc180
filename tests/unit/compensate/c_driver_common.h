/* What both drivers of generated compensation code (c_export_driver.c, c_joint_driver.c) read
 * and compare: a test-vector row of numbers, and a value against the analyzer's. */
#ifndef INERTIA_C_DRIVER_COMMON_H
#define INERTIA_C_DRIVER_COMMON_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

/* The next `count` comma- or line-separated numbers of `f` into `values`; 0 at the end of the file. */
static int read_row(FILE* f, double* values, int count) {
  int i;
  for (i = 0; i < count; ++i) {
    char field[64];
    int n = 0, c;
    while ((c = fgetc(f)) != EOF && c != ',' && c != '\n') {
      if (n < 63) field[n++] = (char)c;
    }
    if (c == EOF && n == 0) return 0;
    field[n] = '\0';
    values[i] = strtod(field, NULL);
  }
  return 1;
}

/* Whether `got` is within `tolerance` of `want` relative to max(|want|, floor), both NaN counting
 * as equal; the largest such error so far in `worst`. */
static int close_enough(double got, double want, double tolerance, double floor, double* worst) {
  double scale, error;
  if (isnan(want) || isnan(got)) return isnan(want) && isnan(got);
  scale = fabs(want) > floor ? fabs(want) : floor;
  error = fabs(got - want) / scale;
  if (error > *worst) *worst = error;
  return error <= tolerance;
}

#endif
