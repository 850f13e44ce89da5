# Written by bench/speed_vs_error; run from docs/speed-vs-error/: gnuplot plots.gp
set terminal svg size 900,600 dynamic font 'sans,12'
set logscale xy
set grid
set key outside right
set xlabel 'wall time (s), AMD EPYC, 2 threads'
set ylabel 'relative RMS error sqrt(relMSE)'
set output 'error_vs_time.svg'
set title 'Error against time, default strategies (commit ddd9434, AMD EPYC, 2 threads)' noenhanced
plot \
  'cbox_no_light.dat' using 2:(sqrt($3)) with linespoints lw 2 title 'cbox_no_light' noenhanced, \
  0.0788361*sqrt(0.00210847/x) with lines dt 2 lc 1 notitle, \
  'cbox_no_light_refraction.dat' using 2:(sqrt($3)) with linespoints lw 2 title 'cbox_no_light_refraction' noenhanced, \
  0.0897133*sqrt(0.00257259/x) with lines dt 2 lc 2 notitle, \
  'cbox_area_light.dat' using 2:(sqrt($3)) with linespoints lw 2 title 'cbox_area_light' noenhanced, \
  0.318756*sqrt(0.000647167/x) with lines dt 2 lc 3 notitle, \
  'cbox_env_light.dat' using 2:(sqrt($3)) with linespoints lw 2 title 'cbox_env_light' noenhanced, \
  1.4065*sqrt(0.00271356/x) with lines dt 2 lc 4 notitle, \
  'sky_sun.dat' using 2:(sqrt($3)) with linespoints lw 2 title 'sky_sun' noenhanced, \
  0.661484*sqrt(0.00390396/x) with lines dt 2 lc 5 notitle
set xlabel 'CPU seconds (all threads), AMD EPYC, 2 threads'
set output 'cmp0.svg'
set title 'Area light on cbox_area_light (small light): auto (default) vs solid angle vs area' noenhanced
plot \
  'cmp0_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'auto' noenhanced, \
  'cmp0_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'solid_angle' noenhanced, \
  'cmp0_2.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'area' noenhanced
set output 'cmp1.svg'
set title 'Area light on cbox_large_light (light over most of the ceiling): auto (default) vs solid angle vs area' noenhanced
plot \
  'cmp1_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'auto' noenhanced, \
  'cmp1_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'solid_angle' noenhanced, \
  'cmp1_2.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'area' noenhanced
set output 'cmp2.svg'
set title 'Environment on sky_sun: MIS (default) vs importance vs cosine vs uniform' noenhanced
plot \
  'cmp2_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'mis' noenhanced, \
  'cmp2_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'importance' noenhanced, \
  'cmp2_2.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'cosine' noenhanced, \
  'cmp2_3.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'uniform' noenhanced
set output 'cmp3.svg'
set title 'Environment on cbox_env_light (constant map: MIS and importance fall back to cosine)' noenhanced
plot \
  'cmp3_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'mis' noenhanced, \
  'cmp3_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'cosine' noenhanced, \
  'cmp3_2.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'uniform' noenhanced
set output 'cmp4.svg'
set title 'Environment distribution on sky_sun: bilinear support (fixed) vs raw pixels (before the fix), MIS' noenhanced
plot \
  'cmp4_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'bilinear-support mis' noenhanced, \
  'cmp4_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'raw-pixel mis' noenhanced
set output 'cmp5.svg'
set title 'Environment distribution on sky_sun: bilinear support (fixed) vs raw pixels, importance only' noenhanced
plot \
  'cmp5_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'bilinear-support importance' noenhanced, \
  'cmp5_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'raw-pixel importance' noenhanced
set output 'cmp6.svg'
set title 'BVH: SAH (default) vs median split, cbox_area_light (36 triangles)' noenhanced
plot \
  'cmp6_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'sah' noenhanced, \
  'cmp6_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'median' noenhanced
set output 'cmp7.svg'
set title 'BVH: SAH (default) vs median split, sky_sun' noenhanced
plot \
  'cmp7_0.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'sah' noenhanced, \
  'cmp7_1.dat' using 6:(sqrt($3)) with linespoints lw 2 title 'median' noenhanced
