#include <math.h>

typedef double k_real;
#define K_USE_FLOAT 0
#define K_LIT(x) x
$macros

$functions
