; filter: conditional output. y = the elements of x greater than 0.5 (fp32), in stream
; order: each cluster tests its element and the clusters whose condition code is set append
; to y in cluster order.
;
; Timing (gold8: stream 3, fp_add 4), consumers at least latency + 1 after producers.
kernel filter
in x
out y

    imm 0.5 -> add0.a[0]                                ; the threshold
loop stream x:
    sin0 x -> add0.b[0], sout.data[0]                   ; t0, lands t3
    nop                                                 ; t1
    nop                                                 ; t2
    nop                                                 ; t3
    add0 flt a[0], b[0] -> cc[0]                        ; t4: 0.5 < x, lands t8
    nop                                                 ; t5
    nop                                                 ; t6
    nop                                                 ; t7
    nop                                                 ; t8
    sout y, data[0] if cc[0]                            ; t9
end
done
