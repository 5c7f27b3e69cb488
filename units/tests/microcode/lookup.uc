; lookup: scratchpad table lookup. A 16-word table is loaded into every cluster's
; scratchpad at address 16..31, then y[i] = table[x[i]] for int32 indices 0..15.
;
; The table stream holds each entry once per cluster (entry j at elements j*C .. j*C+C-1,
; C the cluster count), so every cluster receives the whole table, whatever C is.
;
; Timing (gold8: stream 3, int 2, scratchpad read 2 / write 1), consumers at least
; latency + 1 after producers.
kernel lookup
in table
in x
out y

    imm 0 -> add0.a[0], sp0.addr[0]                     ; j = 0
    imm 1 -> add0.b[0]                                  ; 1
loop count 16:
    sin0 table -> sp0.data[0]                           ; t0, lands t3
    nop                                                 ; t1
    nop                                                 ; t2
    nop                                                 ; t3
    sp0 st 16, addr[0], data[0] | add0 iadd a[0], b[0] -> add0.a[0], sp0.addr[0] ; t4: table[j], j+1 lands t6
end
loop stream x:
    sin0 x -> sp0.addr[1]                               ; t0, lands t3
    nop                                                 ; t1
    nop                                                 ; t2
    nop                                                 ; t3
    sp0 ld 16, addr[1] -> sout.data[0]                  ; t4, lands t6
    nop                                                 ; t5
    nop                                                 ; t6
    sout y, data[0]                                     ; t7
end
done
