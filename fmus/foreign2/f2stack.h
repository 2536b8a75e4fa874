/* Drill point and layered CFRP/Ti/Al stack of the foreign2 plants (issue 20), written apart
 * from fmus/common/drill.c and fmus/foreign/cut.c. Equations: README.md of either plant.
 *
 * The uncut material surface under the drill (the cut front, c) is pushed by the tool tip x
 * through a contact spring k_con and damper d_con. The front advances by the feed per
 * revolution that the spring force can cut: f = (F / K(c))^(1/x_feed) mm/rev, so a steady
 * feed f gives the thrust F = K f^x_feed. K(c) weighs the layers by the share of the conical
 * drill point inside each (linear over the point length L_pt), grown by tool wear; within
 * t_exit of a free lower face (the last layer, or one with a gap below) the uncut rest bends
 * away and K falls as (r / t_exit)^1.5: the push-out. */
#ifndef F2STACK_H
#define F2STACK_H

/* value references of the stack block, the same in both foreign2 plants */
enum {
    F2S_SURFACE = 100, F2S_NLAYERS, F2S_MAT1, F2S_MAT2, F2S_MAT3, F2S_MAT4,
    F2S_T1, F2S_T2, F2S_T3, F2S_T4, F2S_GAP2, F2S_GAP3, F2S_GAP4,
    F2S_KL1, F2S_KL2, F2S_KL3, F2S_KL4, F2S_K_CFRP, F2S_K_TI, F2S_K_AL, F2S_X_FEED,
    F2S_L_PT, F2S_T_EXIT, F2S_K_CON, F2S_D_CON, F2S_HOLES, F2S_W_CFRP, F2S_W_TI, F2S_W_AL,
    F2S_DYN_NOISE, F2S_SEED
};

typedef struct {
    int n;
    double top[4], bot[4];          /* m, along the feed */
    double K[4];                    /* N at 1 mm/rev, worn */
    int mat[4], free_below[4];
    double K_air;                   /* N: below it nothing is cut */
    double inv_x, inv_Lpt, inv_tex; /* 1/x_feed, 1/m, 1/m */
    double k_con, d_con;            /* N/m, N s/m */
} F2Stack;

void f2s_setup(F2Stack *st, const double *val);
/* layers in use need a thickness > 0; returns the 1-based index of the first bad one, 0 if none */
int f2s_bad_layer(const double *val);
double f2s_k(const F2Stack *st, double c);
/* advance the front *c over h [s] for tip x [m], tip velocity v [m/s], spindle n [rev/s];
 * returns the contact force on the tool, >= 0 [N] */
double f2s_step(const F2Stack *st, double *c, double x, double v, double n, double h);
void f2s_where(const F2Stack *st, double x, double *layer, double *material);

#endif
