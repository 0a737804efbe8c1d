// POV-Ray 3.7 translation of scenes/paper/a_glass.json, written by bench/accuracy/povscene.py.
// Conventions of ../../shared/SHADING.md as far as POV-Ray allows.
// Shading that POV-Ray 3.7 cannot match exactly (SHADING.md vs this file):
// - transparent shadows: POV-Ray multiplies a shadow ray by the pigment's
//   transmit T at every surface it crosses (T^2 through a solid) and never cuts
//   it off; Locus uses the Fresnel factors (1-r_a)(1-r_b) of eq. (3), with
//   r = 1 beyond the critical angle. Lambert-Beer absorption matches.
// - total internal reflection: POV-Ray adds the internally reflected ray
//   unweighted; Locus weights it by T.
// - no hither plane in POV-Ray; Locus ignores eye-ray hits nearer than hither.
// - pixel sampling and anti-aliasing are POV-Ray's own (+AM1/+AM2, jitter).
#version 3.7;
global_settings { assumed_gamma 1.0 ambient_light rgb <1, 1, 1> max_trace_level 5 adc_bailout 1/512 }
camera {
  perspective
  location <6.5, 5, 10>
  direction <-0.501551286, -0.331533901, -0.79908171>
  right <0.61655418, 0, -0.386986135> * image_width / image_height
  up <-0.128299023, 0.686770563, -0.204408613>
}
background { rgb <0.08, 0.09, 0.12> }
light_source { <-10, 6, -4> rgb <1, 1, 1> }
#declare m0_tex = texture {
  pigment { rgbt <0.86, 0.83, 0.76, 0> }
  finish { ambient 0.162 diffuse 0.9 }
}
#declare m1_tex = texture {
  pigment { rgbt <0.55, 0.62, 0.7, 0> }
  finish { ambient 0.144 diffuse 0.8 }
}
#declare m2_tex = texture {
  pigment { rgbt <0.85, 0.15, 0.12, 0> }
  finish { ambient 0.162 diffuse 0.9 }
}
#declare m3_tex = texture {
  pigment { rgbt <0.15, 0.3, 0.85, 0> }
  finish { ambient 0.162 diffuse 0.9 }
}
#declare m4_tex = texture {
  pigment { rgbt <0.9, 0.75, 0.15, 0> }
  finish { ambient 0.162 diffuse 0.9 }
}
#declare m5_tex = texture {
  pigment { rgbt <1, 1, 1, 0.92> }
  finish { ambient 0 diffuse 0 phong 0.08 phong_size 200 reflection { 0.08 } }
}
#declare m5_int = interior { ior 1.52 }
#declare m6_tex = texture {
  pigment { rgbt <1, 1, 1, 0.92> }
  finish { ambient 0 diffuse 0 phong 0.08 phong_size 200 reflection { 0.08 } }
}
#declare m6_int = interior { ior 1.52 fade_power 1001 fade_distance 4 fade_color <0, 0.68, 0.84> }
// floor
box { <-25, -0.2, -25>, <25, 0, 25>
  texture { m0_tex }
}
// back wall
box { <-25, 0, -9.5>, <25, 9, -9>
  texture { m1_tex }
}
// stand
mesh {
  triangle { <-0.650561835, 0.01, -1.57059521>, <-1.57059521, 0.01, -0.650561835>, <-1.57059521, 0.41, -0.650561835> }
  triangle { <-0.650561835, 0.01, -1.57059521>, <-1.57059521, 0.41, -0.650561835>, <-0.650561835, 0.41, -1.57059521> }
  triangle { <-1.57059521, 0.01, -0.650561835>, <-1.57059521, 0.01, 0.650561835>, <-1.57059521, 0.41, 0.650561835> }
  triangle { <-1.57059521, 0.01, -0.650561835>, <-1.57059521, 0.41, 0.650561835>, <-1.57059521, 0.41, -0.650561835> }
  triangle { <-1.57059521, 0.01, 0.650561835>, <-0.650561835, 0.01, 1.57059521>, <-0.650561835, 0.41, 1.57059521> }
  triangle { <-1.57059521, 0.01, 0.650561835>, <-0.650561835, 0.41, 1.57059521>, <-1.57059521, 0.41, 0.650561835> }
  triangle { <-0.650561835, 0.01, 1.57059521>, <0.650561835, 0.01, 1.57059521>, <0.650561835, 0.41, 1.57059521> }
  triangle { <-0.650561835, 0.01, 1.57059521>, <0.650561835, 0.41, 1.57059521>, <-0.650561835, 0.41, 1.57059521> }
  triangle { <0.650561835, 0.01, 1.57059521>, <1.57059521, 0.01, 0.650561835>, <1.57059521, 0.41, 0.650561835> }
  triangle { <0.650561835, 0.01, 1.57059521>, <1.57059521, 0.41, 0.650561835>, <0.650561835, 0.41, 1.57059521> }
  triangle { <1.57059521, 0.01, 0.650561835>, <1.57059521, 0.01, -0.650561835>, <1.57059521, 0.41, -0.650561835> }
  triangle { <1.57059521, 0.01, 0.650561835>, <1.57059521, 0.41, -0.650561835>, <1.57059521, 0.41, 0.650561835> }
  triangle { <1.57059521, 0.01, -0.650561835>, <0.650561835, 0.01, -1.57059521>, <0.650561835, 0.41, -1.57059521> }
  triangle { <1.57059521, 0.01, -0.650561835>, <0.650561835, 0.41, -1.57059521>, <1.57059521, 0.41, -0.650561835> }
  triangle { <0.650561835, 0.01, -1.57059521>, <-0.650561835, 0.01, -1.57059521>, <-0.650561835, 0.41, -1.57059521> }
  triangle { <0.650561835, 0.01, -1.57059521>, <-0.650561835, 0.41, -1.57059521>, <0.650561835, 0.41, -1.57059521> }
  triangle { <0.650561835, 0.01, -1.57059521>, <1.57059521, 0.01, -0.650561835>, <1.57059521, 0.01, 0.650561835> }
  triangle { <0.650561835, 0.01, -1.57059521>, <1.57059521, 0.01, 0.650561835>, <0.650561835, 0.01, 1.57059521> }
  triangle { <0.650561835, 0.01, -1.57059521>, <0.650561835, 0.01, 1.57059521>, <-0.650561835, 0.01, 1.57059521> }
  triangle { <0.650561835, 0.01, -1.57059521>, <-0.650561835, 0.01, 1.57059521>, <-1.57059521, 0.01, 0.650561835> }
  triangle { <0.650561835, 0.01, -1.57059521>, <-1.57059521, 0.01, 0.650561835>, <-1.57059521, 0.01, -0.650561835> }
  triangle { <0.650561835, 0.01, -1.57059521>, <-1.57059521, 0.01, -0.650561835>, <-0.650561835, 0.01, -1.57059521> }
  triangle { <-0.650561835, 0.41, -1.57059521>, <-1.57059521, 0.41, -0.650561835>, <-1.57059521, 0.41, 0.650561835> }
  triangle { <-0.650561835, 0.41, -1.57059521>, <-1.57059521, 0.41, 0.650561835>, <-0.650561835, 0.41, 1.57059521> }
  triangle { <-0.650561835, 0.41, -1.57059521>, <-0.650561835, 0.41, 1.57059521>, <0.650561835, 0.41, 1.57059521> }
  triangle { <-0.650561835, 0.41, -1.57059521>, <0.650561835, 0.41, 1.57059521>, <1.57059521, 0.41, 0.650561835> }
  triangle { <-0.650561835, 0.41, -1.57059521>, <1.57059521, 0.41, 0.650561835>, <1.57059521, 0.41, -0.650561835> }
  triangle { <-0.650561835, 0.41, -1.57059521>, <1.57059521, 0.41, -0.650561835>, <0.650561835, 0.41, -1.57059521> }
  inside_vector <0.123, 0.456, 0.789>
  texture { m6_tex } interior { m6_int }
}
// glass cylinder
cylinder { <0, 0.42, 0>, <0, 3.02, 0>, 0.8
  texture { m5_tex } interior { m5_int }
}
// red box
box { <-4.8, 0, -4.4>, <-3.2, 1.6, -2.8>
  texture { m2_tex }
}
// blue box
box { <-0.6, 0, -1>, <0.6, 2.4, 0.2>
  matrix <0.866025403784, 0, -0.5, 0, 1, 0, 0.5, 0, 0.866025403784, -1.2, 0, -4.6>
  texture { m3_tex }
}
// yellow ball
sphere { <1.8, 0.7, -3.2>, 0.7
  texture { m4_tex }
}
