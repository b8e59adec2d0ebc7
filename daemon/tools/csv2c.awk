# csv2c.awk — examples/paper_4x4.csv (i,j,footprint,x,y,T,I,F) to C.
BEGIN { FS = ","; print "/* Generated from examples/paper_4x4.csv by daemon/tools/csv2c.awk. */";
        print "#include \"paper_data.h\""; print "const struct paper_row paper_data_rows[] = {" }
NR == 1 { if ($0 !~ /^i,j,footprint,x,y,T,I,F/) { print "bad header" > "/dev/stderr"; exit 1 } next }
NF == 8 { gsub(/\r/, "", $8);
          printf "    { %d, %d, \"%s\", { \"%s\", \"%s\", \"%s\", \"%s\", \"%s\" } },\n", $1, $2, $3, $4, $5, $6, $7, $8 }
END { print "};"; print "const size_t paper_data_nrows = sizeof paper_data_rows / sizeof paper_data_rows[0];" }
