#include <math.h>
/* two-inertia backlash plant, fixed-step symplectic Euler; Karnopp or LuGre friction on each side.
 p: rb1 rb2 k c b J1 J2 d1 d2 tc1 tc2 law(0 karnopp,1 lugre,2 tanh) sigma0 sigma1 vs ts_ratio TL nopull
 ctrl: mode(0 open loop torque array, 1 PD on ref) kp kd umax q1 (quantum for ctrl) N delay
 in: n samples, sub steps per sample, Ts; u_or_ref[n]; out: U[n], TH1[n], TH2[n] */
static double fric(double w, double Tn, double tc, double d, double J, double h, int *stick) {
  double dv = 1e-7; *stick = 0;
  if (fabs(w) < dv) { if (fabs(Tn) <= tc) { *stick = 1; return Tn; } return tc * (Tn > 0 ? 1 : -1); }
  return tc * (w > 0 ? 1 : -1) + d * w;
}
int simulate(const double *p, const double *ctrl, int n, int sub, double Ts, const double *uin,
             double *U, double *TH1, double *TH2) {
  double rb1=p[0], rb2=p[1], k=p[2], c=p[3], b=p[4], J1=p[5], J2=p[6], d1=p[7], d2=p[8], tc1=p[9], tc2=p[10];
  int law=(int)p[11]; double s0=p[12], s1=p[13], vs=p[14], tsr=p[15], TL=p[16]; int nopull=(int)p[17];
  int mode=(int)ctrl[0]; double kp=ctrl[1], kd=ctrl[2], umax=ctrl[3], q=ctrl[4], N=ctrl[5]; int delay=(int)ctrl[6];
  double x1=0,w1=0,x2=0,w2=0,z1=0,z2=0, h=Ts/sub, mprev=0, upend=0;
  for (int i=0;i<n;i++) {
    TH1[i]=x1; TH2[i]=x2;
    double u;
    if (mode==0) u=uin[i];
    else { double m = q>0 ? floor(x1/q)*q : x1; u = kp*(N*uin[i]-m) - kd*(i? (m-mprev)/Ts : 0); mprev=m;
           if (u>umax) u=umax; if (u<-umax) u=-umax;
           if (delay) { double t=u; u=upend; upend=t; } }
    U[i]=u;
    for (int j=0;j<sub;j++) {
      double s=rb1*x1-rb2*x2, sd=rb1*w1-rb2*w2, F=0;
      if (s>b) F=k*(s-b)+c*sd; else if (s<-b) F=k*(s+b)+c*sd;
      if (nopull) { if (s>b && F<0) F=0; if (s<-b && F>0) F=0; }
      double T1=u-rb1*F, T2=rb2*F+TL, f1, f2; int st1=0, st2=0;
      if (law==0) { f1=fric(w1,T1,tc1,d1,J1,h,&st1); f2=fric(w2,T2,tc2,d2,J2,h,&st2);
        /* Karnopp: stick if speed crosses zero within the step */ }
      else if (law==1) { /* LuGre */
        double g1=tc1*(1+(tsr-1)*exp(-(w1/vs)*(w1/vs))), g2=tc2*(1+(tsr-1)*exp(-(w2/vs)*(w2/vs)));
        double dz1 = g1>0 ? w1 - s0*fabs(w1)*z1/g1 : 0, dz2 = g2>0 ? w2 - s0*fabs(w2)*z2/g2 : 0;
        f1 = s0*z1 + s1*dz1 + d1*w1; f2 = s0*z2 + s1*dz2 + d2*w2;
        z1 += h*dz1; z2 += h*dz2; if (g1<=0) z1=0; if (g2<=0) z2=0; }
      else { double e=1e-3; f1=tc1*tanh(w1/e)+d1*w1; f2=tc2*tanh(w2/e)+d2*w2; }
      double a1=(T1-f1)/J1, a2=(T2-f2)/J2;
      if (st1) { w1=0; a1=0; } if (st2) { w2=0; a2=0; }
      double w1n=w1+h*a1, w2n=w2+h*a2;
      if (law==0) { /* a zero crossing of speed within a step: stop there, stick decided next step */
        if (w1!=0 && w1n*w1<0) w1n=0; if (w2!=0 && w2n*w2<0) w2n=0; }
      w1=w1n; w2=w2n; x1+=h*w1; x2+=h*w2;
    }
  }
  return 0;
}
