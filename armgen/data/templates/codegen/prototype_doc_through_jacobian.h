/* $function: $description.
 * ops: $ops (calls ${p}_jacobian and ${p}_$twin); work: $work_reals reals. */
