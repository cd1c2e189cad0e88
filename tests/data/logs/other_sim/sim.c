#include <math.h>
/* Independent geared-servo simulator: symplectic Euler at a fixed micro-step, implicit (time-stepping)
   Coulomb friction, linear or no-pull mesh with backlash, PD(+I) loop on the motor encoder. */
static double quant(double th, double q){ return q > 0 ? floor(th/q)*q : th; }
int run(int n, double Ts, int nsub, const double *P, const double *C,
        const double *ref, const double *vel, const double *acc, const double *uol,
        const double *nz1, double *x0, double *out_u, double *out_t1, double *out_t2, double *out_m1)
{
    double J1=P[0],J2=P[1],rb1=P[2],rb2=P[3],k=P[4],c=P[5],b=P[6],d1=P[7],d2=P[8],Tc1=P[9],Tc2=P[10],TL=P[11];
    int nopull=(int)P[12]; double umax=P[13], q1=P[14], N=rb2/rb1;
    double Kp=C[0],Kd=C[1],Ki=C[2],Jff=C[3],dff=C[4],alpha=C[5],cff=C[6];
    double th1=x0[0],th2=x0[1],w1=x0[2],w2=x0[3];
    double h=Ts/nsub, integ=0, west=0, mprev=quant(th1+nz1[0],q1);
    for(int i=0;i<n;i++){
        double m=quant(th1+nz1[i],q1);
        out_t1[i]=th1; out_t2[i]=th2; out_m1[i]=m;
        double wr=(i>0)?(m-mprev)/Ts:0; mprev=m;
        west=alpha*west+(1-alpha)*wr;
        double e=N*ref[i]-m;
        integ+=Ki*e*Ts;
        double u=Kp*e+Kd*(N*vel[i]-west)+integ+Jff*N*acc[i]+dff*N*vel[i]+uol[i];
        if(cff>0 && fabs(vel[i])>1e-6) u+=cff*(vel[i]>0?1:-1);
        if(u>umax)u=umax; if(u<-umax)u=-umax;
        out_u[i]=u;
        for(int j=0;j<nsub;j++){
            double s=rb1*th1-rb2*th2, sd=rb1*w1-rb2*w2, F=0;
            if(s>b){F=k*(s-b)+c*sd; if(nopull&&F<0)F=0;}
            else if(s<-b){F=k*(s+b)+c*sd; if(nopull&&F>0)F=0;}
            double T1=u-rb1*F-d1*w1, T2=rb2*F-d2*w2+TL;
            double w=w1+h*T1/J1, f=h*Tc1/J1;
            if(fabs(w)<=f) w1=0; else w1=w-(w>0?f:-f);
            w=w2+h*T2/J2; f=h*Tc2/J2;
            if(fabs(w)<=f) w2=0; else w2=w-(w>0?f:-f);
            th1+=h*w1; th2+=h*w2;
            if(!isfinite(th1)||!isfinite(th2)) return -1-i;
        }
    }
    x0[0]=th1;x0[1]=th2;x0[2]=w1;x0[3]=w2;
    return 0;
}
