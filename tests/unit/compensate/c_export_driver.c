/* Runs generated compensation code (prefix "model") on a test-vector file and compares it with
 * the analyzer's answer: the same flag, the value within a relative tolerance of
 * max(|expected|, floor), and u_coefficients and u_noise (derivatives of the model, computed in
 * the code's precision) within 1000 times that of their own size.
 * Usage: driver VECTORS.csv RELATIVE_TOLERANCE FLOOR */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "c_driver_common.h"
#include "model.h"

int main(int argc, char** argv) {
  FILE* f;
  char header[4096];
  double row[MODEL_INPUTS + 5];
  model_real inputs[MODEL_INPUTS > 0 ? MODEL_INPUTS : 1];
  model_state state;
  double tolerance, floor, worst = 0.0, worst_u = 0.0;
  long rows = 0, bad = 0;
  int i;
  if (argc != 4) return 2;
  tolerance = strtod(argv[2], NULL);
  floor = strtod(argv[3], NULL);
  f = fopen(argv[1], "r");
  if (f == NULL || fgets(header, sizeof header, f) == NULL) return 2;
  model_init(&state);
  while (read_row(f, row, MODEL_INPUTS + 5)) {
    model_result r;
    for (i = 0; i < MODEL_INPUTS; ++i) inputs[i] = (model_real)row[1 + i];
    r = model_compensate(&state, inputs, (model_real)row[0]);
    ++rows;
    if (r.flag != (int)row[MODEL_INPUTS + 4] || !close_enough(r.value, row[MODEL_INPUTS + 1], tolerance, floor, &worst) ||
        !close_enough(r.u_coefficients, row[MODEL_INPUTS + 2], 1e3 * tolerance, 0.0, &worst_u) ||
        !close_enough(r.u_noise, row[MODEL_INPUTS + 3], 1e3 * tolerance, 0.0, &worst_u)) {
      if (bad < 5) {
        fprintf(stderr, "row %ld: value %.17g flag %d, expected %.17g flag %d\n", rows, (double)r.value, r.flag,
                row[MODEL_INPUTS + 1], (int)row[MODEL_INPUTS + 4]);
      }
      ++bad;
    }
  }
  printf("%ld rows, %ld disagree, largest relative difference %.3g (values), %.3g (u)\n", rows, bad, worst, worst_u);
  return bad == 0 && rows > 0 ? 0 : 1;
}
