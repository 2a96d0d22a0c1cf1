#include "${p}.h"

#include <math.h>

/* Every function below is straight-line code from the SX algorithm (fixed-count loops
 * are kept once, as for loops, at the end); w<k> are the algorithm's work registers.
 * Literals and math calls go through the precision macros. */

$definitions
