; madd: streaming multiply-add, z[i] = x[i] * y[i] + w[i] (fp32), one element per cluster
; per iteration, no software pipelining.
;
; Timing (gold8 latencies: stream 3, mul 4, fp_add 4): every consumer issues at least
; latency + 1 cycles after its producer, so the program is right whether a result can be
; read in the cycle it lands or only in the next one. Cycle numbers are within an iteration.
kernel madd
in x
in y
in w
out z

loop stream x:
    sin0 x -> mul0.a[0] | sin1 y -> mul0.b[0] | sin2 w -> add0.b[0]    ; t0, land t3
    nop                                                                 ; t1
    nop                                                                 ; t2
    nop                                                                 ; t3
    mul0 fmul a[0], b[0] -> add0.a[0]                                   ; t4, lands t8
    nop                                                                 ; t5
    nop                                                                 ; t6
    nop                                                                 ; t7
    nop                                                                 ; t8
    add0 fadd a[0], b[0] -> sout.data[0]                                ; t9, lands t13
    nop                                                                 ; t10
    nop                                                                 ; t11
    nop                                                                 ; t12
    nop                                                                 ; t13
    sout z, data[0]                                                     ; t14
end
done
