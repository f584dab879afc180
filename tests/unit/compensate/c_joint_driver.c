/* Runs generated joint compensation code (prefix "model", c_export.hpp's generate_joint_c) on a
 * test-vector file and compares it with the analyzer's answer: the same flag, each unknown within
 * a relative tolerance of max(|expected|, floor), and its u_coefficients and u_noise within 1000
 * times that of their own size.
 * Usage: driver VECTORS.csv RELATIVE_TOLERANCE FLOOR */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "c_driver_common.h"
#include "model.h"

enum { COLUMNS = MODEL_OUTPUTS + MODEL_INPUTS + 3 * MODEL_UNKNOWNS + 1 };

int main(int argc, char** argv) {
  FILE* f;
  char header[8192];
  double row[COLUMNS];
  model_real inputs[MODEL_INPUTS > 0 ? MODEL_INPUTS : 1], y[MODEL_OUTPUTS];
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
  while (read_row(f, row, COLUMNS)) {
    model_result r;
    const double* want = row + MODEL_OUTPUTS + MODEL_INPUTS;
    int ok;
    for (i = 0; i < MODEL_OUTPUTS; ++i) y[i] = (model_real)row[i];
    for (i = 0; i < MODEL_INPUTS; ++i) inputs[i] = (model_real)row[MODEL_OUTPUTS + i];
    r = model_compensate(&state, inputs, y);
    ++rows;
    ok = r.flag == (int)want[3 * MODEL_UNKNOWNS];
    for (i = 0; i < MODEL_UNKNOWNS; ++i) {
      ok = close_enough(r.value[i], want[i], tolerance, floor, &worst) && ok;
      ok = close_enough(r.u_coefficients[i], want[MODEL_UNKNOWNS + i], 1e3 * tolerance, 0.0, &worst_u) && ok;
      ok = close_enough(r.u_noise[i], want[2 * MODEL_UNKNOWNS + i], 1e3 * tolerance, 0.0, &worst_u) && ok;
    }
    if (!ok) {
      if (bad < 5) {
        fprintf(stderr, "row %ld: value[0] %.17g flag %d, expected %.17g flag %d\n", rows, (double)r.value[0], r.flag, want[0],
                (int)want[3 * MODEL_UNKNOWNS]);
      }
      ++bad;
    }
  }
  printf("%ld rows, %ld disagree, largest relative difference %.3g (values), %.3g (u)\n", rows, bad, worst, worst_u);
  return bad == 0 && rows > 0 ? 0 : 1;
}
