within ;
model BallScrewDrive
  "Ball-screw feed drive (Fang et al. 2015, eqs. 1-8, Table 1) with drill and layered workpiece -- Modelica twin of BallScrewDrive.c (docs/plants.md). Not compiled in this project (no Modelica tool). DrillWorkpiece: see fmus/LinearStage/LinearStage.mo."
  import Modelica.Constants.pi;
  import Modelica.Units.SI;

  Modelica.Blocks.Interfaces.RealInput i_ref(unit="A", start=0) "Current reference";
  Modelica.Blocks.Interfaces.RealInput spindle_speed(unit="rpm", start=2000);
  Modelica.Blocks.Interfaces.RealInput orbital_speed(unit="rpm", start=120) "Ripple frequency = orbital_speed/60";

  parameter SI.MomentOfInertia J_e = 0.0003*1.05 "True equivalent inertia (Table 1 nominal 0.0003)";
  parameter Real K_T(unit="N.m/A") = 1.10*0.97 "True torque constant (Table 1 nominal 1.10)";
  parameter Real K_pitch(unit="m/rad") = 0.637e-3 "Table 1";
  parameter Real eta = 0.95 "Table 1";
  parameter SI.Torque tau_coulomb = 0.05;
  parameter SI.Torque tau_stribeck = 0.01;
  parameter SI.AngularVelocity w_stribeck = 0.1;
  parameter Real D_viscous(unit="N.m.s/rad") = 0.01 "D, eq. 3";
  parameter SI.Torque tau_cog = 0.008;
  parameter Real cog_harmonic(unit="1/rev") = 6;
  parameter SI.Time tau_i = 2e-4;
  parameter SI.Current i_noise = 0.01;
  parameter SI.Current i_max = 6;
  parameter SI.Length enc_resolution = 5e-6;
  parameter Integer motor_enc_counts = 131072;
  parameter SI.Position x0 = 0;

  extends DrillWorkpiece(surface=1e-3, ripple_ratio=0.15, ripple_phase=0.6);

  Modelica.Blocks.Interfaces.RealOutput x_enc(unit="m");
  Modelica.Blocks.Interfaces.RealOutput theta_enc(unit="rad");
  Modelica.Blocks.Interfaces.RealOutput i_meas(unit="A");
  Modelica.Blocks.Interfaces.RealOutput F_dyn(unit="N") "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput F_thrust_true(unit="N") "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput F_ripple_true(unit="N") "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput tau_friction_true(unit="N.m") "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput layer "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput material "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput x_tool_true(unit="m") "Scoring only";
  Modelica.Blocks.Interfaces.RealOutput w_m_true(unit="rad/s") "Scoring only";

  SI.Angle theta(start=0, fixed=true);
  SI.AngularVelocity w(start=0, fixed=true);
  SI.Current i_motor(start=0, fixed=true);
  SI.Torque tau_m "eq. 2";
  SI.Torque tau_ext "Reaction torque of the cutting process (inverse of eq. 6)";
  SI.Torque tau_cf "Coulomb (+ Stribeck) friction";
  SI.Torque tau_applied "tau_m - tau_ext - torque ripple";
  Boolean stuck(start=true, fixed=true);
protected
  Modelica.Blocks.Noise.NormalNoise noise_i(samplePeriod=1e-4, mu=0, sigma=i_noise);
  Modelica.Blocks.Noise.NormalNoise noise_F(samplePeriod=1e-4, mu=0, sigma=F_dyn_noise);
  inner Modelica.Blocks.Noise.GlobalSeed globalSeed(fixedSeed=seed);
equation
  z_tool = x0 + K_pitch*theta "rigid screw; contact compliance lives in the cut model";
  v_tool = K_pitch*w;
  n_rps = abs(spindle_speed)/60;
  der(phi_orb) = 2*pi*orbital_speed/60;

  tau_i*der(i_motor) = max(-i_max, min(i_max, i_ref)) - i_motor;
  tau_m = K_T*i_motor                                       "eq. 2";
  tau_ext = F_thrust*K_pitch/eta                            "eq. 6 solved for the torque";
  tau_applied = tau_m - tau_ext - tau_cog*sin(cog_harmonic*theta);
  when {pre(stuck) and abs(tau_applied) > tau_coulomb + tau_stribeck, not pre(stuck) and w*pre(w) <= 0 and abs(tau_applied) <= tau_coulomb + tau_stribeck} then
    stuck = not pre(stuck);
  end when;
  tau_cf = if stuck then tau_applied
           else sign(w)*(tau_coulomb + tau_stribeck*exp(-(w/w_stribeck)^2));
  der(theta) = w;
  // J_e dw/dt = tau_m - tau_d,  tau_d = tau_ext + tau_cf + D w + ripple   (eqs. 1, 3, 4)
  J_e*der(w) = if stuck then 0 else tau_applied - tau_cf - D_viscous*w;

  x_enc = floor(z_tool/enc_resolution)*enc_resolution;
  theta_enc = floor(theta/(2*pi/motor_enc_counts))*(2*pi/motor_enc_counts);
  i_meas = i_motor + noise_i.y;
  F_dyn = F_thrust + noise_F.y;
  F_thrust_true = F_thrust;
  F_ripple_true = F_r;
  tau_friction_true = if stuck then tau_applied else tau_cf + D_viscous*w;
  layer = layer_at;
  material = material_at;
  x_tool_true = z_tool;
  w_m_true = w;
  annotation (experiment(StopTime=0.5, Interval=1e-4));
end BallScrewDrive;
