${p}_real *$name
