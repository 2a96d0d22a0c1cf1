/* $loop: a fixed-count loop the functions above call (not for direct use). */
$prototype
