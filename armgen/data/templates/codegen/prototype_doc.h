/* $function: $description.
 * ops: $ops; work: $work_reals reals. */
