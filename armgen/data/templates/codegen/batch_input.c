const ${p}_real *in$k
