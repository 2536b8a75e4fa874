within ;
model LinearStage
  "Keio z-axis linear-motor stage (Yamamoto & Kakinuma) with drill and layered workpiece -- Modelica twin of LinearStage.c (docs/plants.md). Not compiled in this project (no Modelica tool); kept equation-for-equation with the C code."
  import Modelica.Constants.pi;
  import Modelica.Units.SI;

  // ---------------------------------------------------------------- inputs
  Modelica.Blocks.Interfaces.RealInput i_ref(unit="A", start=0) "Current reference to the drive's current loop";
  Modelica.Blocks.Interfaces.RealInput spindle_speed(unit="rpm", start=3000) "Spindle speed";

  // ---------------------------------------------------------------- machine parameters (true values)
  parameter SI.Mass M = 3.95*1.05 "True moving mass (nominal 3.95 kg)";
  parameter Real Kt(unit="N/A") = 24*0.97 "True thrust constant (nominal 24 N/A)";
  parameter SI.Acceleration g = 9.81;
  parameter SI.Force F_gc = 40.0 "Gravity-compensator force";
  parameter SI.Force F_coulomb = 8.0;
  parameter Real b_viscous(unit="N.s/m") = 30.0;
  parameter SI.Force F_stribeck = 3.0;
  parameter SI.Velocity v_stribeck = 1e-3;
  parameter SI.Time tau_i = 1.5e-4 "Current-loop time constant";
  parameter SI.Current i_noise = 0.02 "Current measurement noise std";
  parameter SI.Current i_max = 10.0;
  parameter SI.Length enc_resolution = 4e-9;
  parameter SI.Force F_cog = 1.0;
  parameter SI.Length cog_pitch = 0.016;
  parameter SI.Position z0 = 0;
  parameter Real orbital_speed(unit="rpm") = 0;

  // ---------------------------------------------------------------- drill / workpiece
  extends DrillWorkpiece(surface=1e-3, ripple_ratio=0, ripple_phase=0);

  // ---------------------------------------------------------------- outputs
  Modelica.Blocks.Interfaces.RealOutput z_enc(unit="m") "Linear encoder (floor-quantised)";
  Modelica.Blocks.Interfaces.RealOutput i_meas(unit="A") "Measured motor current";
  Modelica.Blocks.Interfaces.RealOutput F_dyn(unit="N") "Scoring only: dynamometer thrust";
  Modelica.Blocks.Interfaces.RealOutput F_thrust_true(unit="N") "Scoring only: true thrust";
  Modelica.Blocks.Interfaces.RealOutput F_ripple_true(unit="N") "Scoring only: orbital ripple";
  Modelica.Blocks.Interfaces.RealOutput F_friction_true(unit="N") "Scoring only: friction";
  Modelica.Blocks.Interfaces.RealOutput layer "Scoring only: layer index at the tool tip";
  Modelica.Blocks.Interfaces.RealOutput material "Scoring only: material code at the tool tip";
  Modelica.Blocks.Interfaces.RealOutput z_tool_true(unit="m") "Scoring only: tool-tip position";
  Modelica.Blocks.Interfaces.RealOutput v_true(unit="m/s") "Scoring only: stage velocity";

  // ---------------------------------------------------------------- states
  SI.Position z(start=z0, fixed=true);
  SI.Velocity v(start=0, fixed=true);
  SI.Current i_motor(start=0, fixed=true);
  SI.Force F_ext "All forces except friction";
  SI.Force F_fric;
  Boolean stuck(start=true, fixed=true) "Karnopp stick state";
protected
  Modelica.Blocks.Noise.NormalNoise noise_i(samplePeriod=1e-4, mu=0, sigma=i_noise);
  Modelica.Blocks.Noise.NormalNoise noise_F(samplePeriod=1e-4, mu=0, sigma=F_dyn_noise);
  inner Modelica.Blocks.Noise.GlobalSeed globalSeed(fixedSeed=seed);
equation
  // tool tip = stage
  z_tool = z;
  v_tool = v;
  n_rps = abs(spindle_speed)/60;
  der(phi_orb) = 2*pi*orbital_speed/60;

  // current loop (first-order lag, saturated reference)
  tau_i*der(i_motor) = max(-i_max, min(i_max, i_ref)) - i_motor;

  // M dv/dt = Kt i + M g - F_gc - F_thrust + F_cog sin(2 pi z/p) - F_fric(v)
  F_ext = Kt*i_motor + M*g - F_gc - F_thrust + F_cog*sin(2*pi*z/cog_pitch);
  when {pre(stuck) and abs(F_ext) > F_coulomb + F_stribeck, not pre(stuck) and v*pre(v) <= 0 and abs(F_ext) <= F_coulomb + F_stribeck} then
    stuck = not pre(stuck);
  end when;
  F_fric = if stuck then F_ext
           else sign(v)*(F_coulomb + F_stribeck*exp(-(v/v_stribeck)^2)) + b_viscous*v;
  der(z) = v;
  M*der(v) = if stuck then 0 else F_ext - F_fric;

  // sensors
  z_enc = floor(z/enc_resolution)*enc_resolution;
  i_meas = i_motor + noise_i.y;
  F_dyn = F_thrust + noise_F.y;
  F_thrust_true = F_thrust;
  F_ripple_true = F_r;
  F_friction_true = F_fric;
  layer = layer_at;
  material = material_at;
  z_tool_true = z;
  v_true = v;
  annotation (experiment(StopTime=0.5, Interval=1e-4),
    Documentation(info="<html><p>Fixed-step twin of fmus/LinearStage/LinearStage.c: the FMU integrates these equations with semi-implicit Euler at h_internal = 10 us (see docs/plants.md).</p></html>"));
end LinearStage;

partial model DrillWorkpiece
  "Drill and layered workpiece shared by LinearStage and BallScrewDrive (fmus/common/drill.c)"
  import Modelica.Units.SI;
  parameter SI.Position surface = 1e-3 "Top surface of the stack (feed coordinate)";
  parameter Integer n_layers(min=1, max=4) = 2;
  parameter Integer material_codes[4] = {1, 2, 1, 1} "layerK_material: 1 CFRP, 2 Ti-6Al-4V, 3 aluminium";
  parameter SI.Length thickness[4] = {5e-3, 4.5e-3, 0, 0} "layerK_thickness";
  parameter SI.Length gap[4] = {0, 0, 0, 0} "layerK_gap (gap above layer K)";
  parameter Real kc_layer[4](each unit="N/(m/rev)") = {0, 0, 0, 0} "layerK_kc, 0 = preset";
  parameter Real kc_cfrp(unit="N/(m/rev)") = 2.0e7;
  parameter Real kc_ti(unit="N/(m/rev)") = 6.5e7;
  parameter Real kc_al(unit="N/(m/rev)") = 2.5e6;
  parameter Real ti_descent(unit="1/m") = 20;
  parameter Real ripple_ratio = 0.15;
  parameter SI.Angle ripple_phase = 0.6;
  parameter Real k_contact(unit="N/m") = 5e7;
  parameter Real d_contact(unit="N.s/m") = 5e3;
  parameter SI.Length engage_length = 1e-4;
  parameter SI.Length exit_thinning = 4e-4;
  parameter SI.Length gap_thinning = 1e-4;
  parameter Real wear_holes = 0;
  parameter Real wear_cfrp = 0.2/15;
  parameter Real wear_ti = 0.45/15;
  parameter Real wear_al = 0.05/15;
  parameter SI.Force F_dyn_noise = 1.0;
  parameter Integer seed = 1;
  parameter SI.Time h_internal = 1e-5 "Fixed sub-step of the C implementation";

  final parameter SI.Position top[4] = cat(1, {surface}, {bot[k - 1] + gap[k] for k in 2:4}) "top_1 = surface, top_k = bot_(k-1) + gap_k";
  final parameter SI.Position bot[4] = {top[k] + thickness[k] for k in 1:4};
  final parameter Real kc[4] = {(if kc_layer[k] > 0 then kc_layer[k] else (if material_codes[k] == 1 then kc_cfrp elseif material_codes[k] == 2 then kc_ti else kc_al))
                               *(1 + (if material_codes[k] == 1 then wear_cfrp elseif material_codes[k] == 2 then wear_ti else wear_al)*wear_holes) for k in 1:4};
  final parameter SI.Length thin[4] = {if k == n_layers then exit_thinning elseif k < n_layers and gap[min(k + 1, 4)] > 0 then gap_thinning else 0 for k in 1:4};

  SI.Position z_tool "Tool tip (set by the machine model)";
  SI.Velocity v_tool;
  Real n_rps(unit="1/s") "Spindle revolutions per second";
  SI.Position c(start=surface) "Cut front: uncut material under the tool tip";
  SI.Angle phi_orb(start=0, fixed=true) "Orbital angle";
  Real kc_eff(unit="N/(m/rev)");
  SI.Length e "Penetration z_tool - c";
  Real a(unit="1/s") "Relaxation rate k_contact n / kc_eff";
  SI.Force F_DC, F_r, F_thrust;
  Integer layer_at, material_at;
equation
  // effective thrust coefficient over the engagement zone [c - L, c]
  kc_eff = sum(
    (if c <= top[k] or k > n_layers then 0 else
      (if thin[k] > 0 then max(0, min(1, (bot[k] - c)/thin[k])) else 1)
      *(if material_codes[k] == 2 then exp(-ti_descent*(min(c, bot[k]) - top[k])) else 1)
      *kc[k]*max(0, min(c, bot[k]) - max(c - engage_length, top[k]))/engage_length)
    for k in 1:4);
  e = z_tool - c;
  a = if kc_eff > 0 then k_contact*n_rps/kc_eff else 0;
  // Maxwell contact: dc/dt = k e n / kc_eff while in contact; free advance when nothing is engaged
  der(c) = if kc_eff <= 0 then (if e > 0 then max(v_tool, 0) else 0)
           elseif e > 0 then a*e else 0;
  F_DC = if e > 0 then max(0, k_contact*e + d_contact*(v_tool - a*e)) else 0;
  F_r = ripple_ratio*F_DC*sin(phi_orb + ripple_phase)  "Fang eqs. 7-8";
  F_thrust = F_DC + F_r;
  // scoring: layer and material at the tool tip
  layer_at = max({if k <= n_layers and z_tool >= top[k] and z_tool < bot[k] then k else 0 for k in 1:4});
  material_at = if layer_at > 0 then material_codes[max(1, layer_at)] else 0;
end DrillWorkpiece;
