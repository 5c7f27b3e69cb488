; cond_input: conditional input. For each element of x (int32): if x < 0 it is replaced by
; the next element of y, else kept: z = x < 0 ? next(y) : x. Only the clusters whose
; condition code is set take an element of y, in cluster order, so y is consumed exactly
; as often as x has a negative element.
;
; Timing (gold8: stream 3, int 2), consumers at least latency + 1 after producers.
kernel cond_input
in x
in y
out z

    imm 0 -> add0.b[0]                                  ; zero
loop stream x:
    sin0 x -> add0.a[0], add1.b[0]                      ; t0, lands t3
    nop                                                 ; t1
    nop                                                 ; t2
    nop                                                 ; t3
    add0 ilt_s a[0], b[0] -> cc[0]                      ; t4: x < 0, lands t6
    nop                                                 ; t5
    nop                                                 ; t6
    sin1 y if cc[0] -> add1.a[0]                        ; t7, lands t10 where cc[0]
    nop                                                 ; t8
    nop                                                 ; t9
    nop                                                 ; t10
    add1 select cc[0], a[0], b[0] -> sout.data[0]       ; t11, lands t13
    nop                                                 ; t12
    nop                                                 ; t13
    sout z, data[0]                                     ; t14
end
done
